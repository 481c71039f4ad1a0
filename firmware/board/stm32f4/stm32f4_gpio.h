/*
 * stm32f4_gpio: pin setup from a table (RM0090 section 8): each pin of the
 * board's table gets its mode (alternate function, analog, input), its
 * alternate-function number, pull-up and output speed, after its port clock
 * is enabled.
 */
#ifndef STM32F4_GPIO_H
#define STM32F4_GPIO_H

#include <stddef.h>
#include <stdint.h>

#include "stm32f4_regs.h"

#ifdef __cplusplus
extern "C" {
#endif

#define STM32_GPIO_PORTS 9u  /* A..I */

typedef struct {
    uint8_t port;   /* 0 = A, 1 = B, ... */
    uint8_t pin;    /* 0..15 */
    uint8_t mode;   /* STM32_GPIO_MODE_* */
    uint8_t af;     /* alternate function 0..15 (mode AF) */
    uint8_t pull;   /* 0 none, STM32_GPIO_PULL_UP */
    uint8_t speed;  /* OSPEEDR: 0 low .. 3 very high (edges of fast outputs) */
    const char *use;/* what the board uses it for (documentation) */
} stm32_pin_t;

/* Configures the pins; ports[i] is port i's register block.  Returns 0 or
 * -1 if a pin names a port or pin number that does not exist. */
int stm32_gpio_setup(stm32_rcc_t *rcc, stm32_gpio_t *const *ports, const stm32_pin_t *pins,
                     size_t n);

#ifdef __cplusplus
}
#endif

#endif /* STM32F4_GPIO_H */
