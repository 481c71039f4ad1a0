/*
 * stm32f4_tim: the timers this port uses (RM0090 sections 17 and 18).
 *
 * - The tick: an up-counting timer whose update event, at 1 kHz, raises
 *   the interrupt that runs hd_fw_isr and, through TRGO (CR2.MMS = update),
 *   starts the injected ADC conversion of the bridge at the same instant.
 *   On the boards that is the advanced timer TIM1 (APB2); in QEMU's
 *   netduinoplus2, which models only TIM2..TIM5, it is TIM2.  The register
 *   layout of the time base is the same, so one driver serves both.
 * - Encoder mode (SMCR.SMS = 3): the counter follows a quadrature encoder
 *   on CH1/CH2.  A 16-bit counter is extended to the 32-bit free-running
 *   count the HAL promises by adding the signed 16-bit difference of each
 *   read (correct while fewer than 32768 counts pass between two reads, i.e.
 *   below 32.7 M counts/s at 1 kHz); the firmware's modular deltas then
 *   handle the 32-bit wrap.
 */
#ifndef STM32F4_TIM_H
#define STM32F4_TIM_H

#include <stdbool.h>
#include <stdint.h>

#include "stm32f4_regs.h"

#ifdef __cplusplus
extern "C" {
#endif

typedef struct {
    uint32_t psc;  /* prescaler register value (divider - 1), 0..65535 */
    uint32_t arr;  /* auto-reload value (period - 1) */
} stm32_tim_period_t;

/* The smallest prescaler (finest counter resolution) for which
 * clock_hz / rate_hz splits exactly into (psc + 1) (arr + 1) with
 * arr <= arr_max.  Returns false if there is none (the rate would not be
 * exact). */
bool stm32_tim_period(uint32_t clock_hz, uint32_t rate_hz, uint32_t arr_max,
                      stm32_tim_period_t *out);

/* Configures a stopped up-counter at rate_hz: update interrupt enabled,
 * TRGO on update (the ADC trigger), prescaler loaded by a software update
 * that raises no interrupt (URS).  Returns 0 or HAL_ERR_RANGE when the
 * rate is not exact.  Start with stm32_tick_start. */
int stm32_tick_init(stm32_tim_t *tim, uint32_t clock_hz, uint32_t rate_hz, uint32_t arr_max);
void stm32_tick_start(stm32_tim_t *tim);
void stm32_tick_stop(stm32_tim_t *tim);

/* In the interrupt: clears the update flag; returns true if it was set
 * (false: the interrupt came from something else). */
bool stm32_tick_ack(stm32_tim_t *tim);

typedef struct {
    stm32_tim_t *tim;
    uint8_t counter_bits;  /* 16 (TIM1/3/4/8) or 32 (TIM2/5) */
    uint8_t filter;        /* input filter IC1F/IC2F, 0..15 */
    bool invert;           /* count the other way (swap of A/B) */
} stm32_encoder_config_t;

typedef struct {
    stm32_encoder_config_t cfg;
    uint32_t last_cnt;   /* counter at the last read */
    uint32_t counts;     /* extended free-running count */
} stm32_encoder_t;

/* Encoder mode 3 on CH1/CH2, counter from 0, running. */
void stm32_encoder_init(stm32_encoder_t *enc, const stm32_encoder_config_t *cfg);

/* The free-running 32-bit count (wraps modulo 2^32). */
uint32_t stm32_encoder_counts(stm32_encoder_t *enc);

#ifdef __cplusplus
}
#endif

#endif /* STM32F4_TIM_H */
