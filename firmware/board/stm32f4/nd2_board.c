/*
 * The netduinoplus2 emulator image (hd_nd2.elf): QEMU 7.2's STM32F405 model
 * running the same firmware runner as the mps2-an386 image
 * (../mps2_an386/main_run.c: samples in and CAN frames out over
 * semihosting, one float dump record per tick) on this port's startup,
 * clock code and tick timer driver.
 *
 * What QEMU models and what it does not (hw/arm/stm32f405_soc.c): timers
 * 2..5 (clocked at a fixed 1 GHz of virtual time, whatever the RCC says),
 * ADCs (regular conversions only: no injected group), USARTs, SPI, SYSCFG,
 * EXTI; RCC, flash interface, CAN, IWDG, GPIO and TIM1 are unimplemented
 * (reads 0, writes ignored).  So here:
 *   - the clock code runs and falls back to HSI after its bounded wait for
 *     HSERDY; the image says so on the console;
 *   - the tick is TIM2 (the boards use TIM1), programmed by the same
 *     stm32_tick_init for QEMU's 1 GHz timer clock; its update interrupt
 *     calls main_run.c's tick body (named SysTick_Handler there);
 *   - the ADC driver is exercised once: its injected conversion never
 *     completes and the bounded wait reports it; the samples come from the
 *     stream, as on mps2-an386.
 */
#include <stdint.h>

#include "board.h"
#include "semihost.h"
#include "stm32f4_adc.h"
#include "stm32f4_board.h"
#include "stm32f4_clock.h"
#include "stm32f4_startup.h"
#include "stm32f4_tim.h"

#define ND2_TIM_CLOCK_HZ 1000000000u /* QEMU 7.2: TIM2..5 count virtual nanoseconds */
#define TIM2_REGS ((stm32_tim_t *)STM32_TIM2_BASE)

void TIM2_IRQHandler(void);

void board_systick_start(void)
{
    (void)stm32_tick_init(TIM2_REGS, ND2_TIM_CLOCK_HZ, BOARD_TICK_HZ, 0xFFFFu);
    STM32_NVIC_ISER[STM32_IRQ_TIM2 / 32u] = 1u << (STM32_IRQ_TIM2 % 32u);
    stm32_tick_start(TIM2_REGS);
    /* QEMU arms its timer on a PSC/ARR/EGR write, not on CEN: a second
     * update event starts the count (on a real part it only restarts it). */
    STM32_WR(TIM2_REGS->EGR, STM32_TIM_EGR_UG);
}

void board_systick_stop(void)
{
    stm32_tick_stop(TIM2_REGS);
    STM32_NVIC_ICER[STM32_IRQ_TIM2 / 32u] = 1u << (STM32_IRQ_TIM2 % 32u);
}

void TIM2_IRQHandler(void)
{
    if (stm32_tick_ack(TIM2_REGS)) {
        SysTick_Handler();
    }
}

static void say(const char *a, const char *b)
{
    sh_puts("netduinoplus2: ");
    sh_puts(a);
    sh_puts(b);
    sh_puts("\n");
}

void board_early_init(void)
{
    stm32_clock_config_t cc = {.hse_hz = 8000000u, .sysclk_hz = STM32_BOARD_SYSCLK_HZ,
                               .ready_polls = STM32_BOARD_READY_POLLS};
    stm32_clock_t clk;
    uint32_t faults = stm32_clock_init((stm32_rcc_t *)STM32_RCC_BASE,
                                       (stm32_flash_t *)STM32_FLASH_IF_BASE, &cc, &clk);
    if (faults & STM32_CLOCK_FAULT_HSE) {
        say("clock: HSE not ready within the bound (no RCC model): ",
            "running on the HSI fallback, 16 MHz (HAL_RESET_CLOCK on a board)");
    } else if (faults != 0u) {
        say("clock: ", "PLL or switch fault: running on the HSI fallback");
    } else {
        say("clock: ", "168 MHz from the PLL");
    }
    stm32_adc_drv_t adc;
    stm32_adc_config_t ac = {.adc = (stm32_adc_t *)STM32_ADC1_BASE,
                             .common = (stm32_adc_common_t *)STM32_ADC_COMMON_BASE,
                             .channel = 3u, .jextsel = STM32_ADC_JEXTSEL_TIM2_TRGO,
                             .sample_code = 3u, .adcpre = 1u, .midscale_counts = 2048u,
                             .ready_polls = STM32_BOARD_ADC_POLLS};
    hal_adc_sample_t s;
    if (stm32_adc_init(&adc, &ac) == HAL_OK) {
        stm32_adc_start(&adc);
        if (stm32_adc_read(&adc, &s) == HAL_ERR_IO) {
            say("adc: injected conversion not complete within the bound (not modelled): ",
                "reported as an ADC fault on a board; samples come from the stream");
        } else {
            say("adc: ", "injected conversion completed");
        }
    }
}
