/* stm32f4_gpio: see stm32f4_gpio.h. */
#include "stm32f4_gpio.h"

#define PINS_PER_PORT 16u
#define AFR_PINS 8u

int stm32_gpio_setup(stm32_rcc_t *rcc, stm32_gpio_t *const *ports, const stm32_pin_t *pins,
                     size_t n)
{
    for (size_t i = 0; i < n; i++) {
        if (pins[i].port >= STM32_GPIO_PORTS || pins[i].pin >= PINS_PER_PORT ||
            pins[i].af > 15u || pins[i].mode > STM32_GPIO_MODE_ANALOG || pins[i].speed > 3u) {
            return -1;
        }
    }
    for (size_t i = 0; i < n; i++) {
        const stm32_pin_t *p = &pins[i];
        stm32_gpio_t *g = ports[p->port];
        STM32_SET(rcc->AHB1ENR, STM32_RCC_AHB1ENR_GPIOAEN << p->port);
        uint32_t two = 2u * p->pin;
        uint32_t four = 4u * (p->pin % AFR_PINS);
        stm32_reg_t *afr = &g->AFR[p->pin / AFR_PINS];
        STM32_WR(*afr, (STM32_RD(*afr) & ~(0xFu << four)) | ((uint32_t)p->af << four));
        STM32_WR(g->PUPDR, (STM32_RD(g->PUPDR) & ~(3u << two)) | ((uint32_t)p->pull << two));
        STM32_WR(g->OSPEEDR,
                 (STM32_RD(g->OSPEEDR) & ~(3u << two)) | ((uint32_t)p->speed << two));
        STM32_WR(g->MODER, (STM32_RD(g->MODER) & ~(3u << two)) | ((uint32_t)p->mode << two));
    }
    return 0;
}
