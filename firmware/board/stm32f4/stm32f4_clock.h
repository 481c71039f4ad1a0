/*
 * stm32f4_clock: the clock tree, from an external crystal (HSE, 8 MHz on
 * the ODrive v3 and Mini Cheetah class boards) through the main PLL to the
 * system clock (168 MHz), with the bus prescalers and flash wait states
 * that speed needs (RM0090 section 6 "RCC", section 3 "Embedded flash").
 *
 * Every ready flag is waited for at most `ready_polls` reads.  A crystal
 * that never starts, a PLL that never locks or a switch that never takes
 * effect is a fault, not a hang: the clock stays on (or returns to) the
 * internal 16 MHz HSI oscillator, the fault bits say which step failed, and
 * the frequencies reported are the ones really in effect, so the timer and
 * CAN bit timing are computed from them.  QEMU's STM32F405 has no RCC model
 * (its registers read 0): there the HSE step times out and the image runs
 * on the fallback, which the emulator build reports on its console.
 */
#ifndef STM32F4_CLOCK_H
#define STM32F4_CLOCK_H

#include <stdbool.h>
#include <stdint.h>

#include "stm32f4_regs.h"

#ifdef __cplusplus
extern "C" {
#endif

#define STM32_HSI_HZ 16000000u
#define STM32_PLL_VCO_IN_HZ 2000000u  /* RM0090: 1..2 MHz, 2 MHz for the least jitter */
#define STM32_USB_HZ 48000000u
/* Datasheet maxima (F405; the F446 allows 45/90 MHz, so these fit both). */
#define STM32_PCLK1_MAX_HZ 42000000u
#define STM32_PCLK2_MAX_HZ 84000000u
#define STM32_FLASH_HZ_PER_WS 30000000u /* 2.7..3.6 V: one wait state per 30 MHz */

/* Fault bits of stm32_clock_t.faults. */
#define STM32_CLOCK_FAULT_HSE 0x1u     /* HSERDY never set */
#define STM32_CLOCK_FAULT_PLL 0x2u     /* PLLRDY never set */
#define STM32_CLOCK_FAULT_SWITCH 0x4u  /* SWS never showed the PLL */
#define STM32_CLOCK_FAULT_FLASH 0x8u   /* flash latency did not read back */
#define STM32_CLOCK_FAULT_CONFIG 0x10u /* the requested frequencies have no PLL setting */

typedef struct {
    uint32_t hse_hz;      /* crystal, 4..26 MHz, a multiple of 2 MHz */
    uint32_t sysclk_hz;   /* wanted system clock (AHB = SYSCLK) */
    uint32_t ready_polls; /* bound on every ready-flag wait */
} stm32_clock_config_t;

/* The PLL and prescaler settings for a configuration (pure arithmetic). */
typedef struct {
    uint32_t pllm, plln, pllp, pllq;  /* PLLP as the divider 2, 4, 6 or 8 */
    uint32_t ppre1_div, ppre2_div;    /* APB1, APB2 dividers (1, 2, 4, ...) */
    uint32_t flash_ws;
} stm32_clock_plan_t;

/* The clocks in effect. */
typedef struct {
    uint32_t sysclk_hz;
    uint32_t pclk1_hz, pclk2_hz;        /* APB1 (CAN, TIM2..5), APB2 (TIM1/8, ADC) */
    uint32_t tim_apb1_hz, tim_apb2_hz;  /* timer kernels: x2 when the APB divider > 1 */
    bool on_pll;
    uint32_t faults;                    /* STM32_CLOCK_FAULT_* */
} stm32_clock_t;

/* Computes the plan; returns false if no PLL setting gives sysclk_hz
 * exactly within the manual's limits. */
bool stm32_clock_plan(uint32_t hse_hz, uint32_t sysclk_hz, stm32_clock_plan_t *plan);

/* Runs the sequence HSE on -> PLL on -> flash wait states -> prescalers ->
 * switch, each wait bounded; on a failure returns to HSI.  Fills *out with
 * what is in effect and returns out->faults (0 = everything as asked). */
uint32_t stm32_clock_init(stm32_rcc_t *rcc, stm32_flash_t *flash, const stm32_clock_config_t *cfg,
                          stm32_clock_t *out);

/* The clocks after reset (HSI, all prescalers 1). */
void stm32_clock_hsi(stm32_clock_t *out);

#ifdef __cplusplus
}
#endif

#endif /* STM32F4_CLOCK_H */
