/*
 * stm32f4_adc: the bridge amplifier on one injected ADC channel, converted
 * at each tick (RM0090 section 13).
 *
 * The tick timer's TRGO starts the injected group (CR2.JEXTSEL/JEXTEN) at
 * the update event, the same instant the tick interrupt is raised; the
 * interrupt reads the result in adc_read.  The injected offset register
 * (JOFR1) subtracts the amplifier's mid-scale, so JDR1 holds the signed
 * bridge counts directly.  adc_read waits for JEOC at most `ready_polls`
 * reads: a conversion that never completes (no trigger, ADC off, a dead
 * clock) returns HAL_ERR_IO, which the firmware turns into its ADC fault
 * bit, and is counted here.
 */
#ifndef STM32F4_ADC_H
#define STM32F4_ADC_H

#include <stdint.h>

#include "hal.h"
#include "stm32f4_regs.h"

#ifdef __cplusplus
extern "C" {
#endif

#define STM32_ADC_FULL_SCALE 4095u  /* 12-bit */

typedef struct {
    stm32_adc_t *adc;
    stm32_adc_common_t *common;
    uint8_t channel;         /* ADCx_IN0..15 */
    uint8_t jextsel;         /* STM32_ADC_JEXTSEL_*: the tick timer's TRGO */
    uint8_t sample_code;     /* SMPx: 0 = 3 cycles .. 7 = 480 cycles */
    uint8_t adcpre;          /* ADC clock = PCLK2 / (2 (adcpre + 1)); <= 36 MHz */
    uint16_t midscale_counts;/* subtracted by JOFR1 (2048 for a mid-rail amplifier) */
    uint32_t ready_polls;    /* bound on the JEOC wait */
} stm32_adc_config_t;

typedef struct {
    stm32_adc_config_t cfg;
    uint32_t conversions;
    uint32_t timeouts;       /* JEOC never came */
} stm32_adc_drv_t;

/* Configures and powers the ADC for triggered injected conversions;
 * returns 0 or HAL_ERR_RANGE (channel, code or offset out of range). */
int stm32_adc_init(stm32_adc_drv_t *drv, const stm32_adc_config_t *cfg);

/* hal_sensors_t.adc_read: the conversion of this tick.  saturated is set at
 * either rail (raw 0 or 4095). */
int stm32_adc_read(void *ctx, hal_adc_sample_t *out);

/* Starts one injected conversion by software (JSWSTART): self-test and
 * bench; the tick uses the timer trigger. */
void stm32_adc_start(stm32_adc_drv_t *drv);

#ifdef __cplusplus
}
#endif

#endif /* STM32F4_ADC_H */
