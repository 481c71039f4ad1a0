/* stm32f4_tim: see stm32f4_tim.h. */
#include "stm32f4_tim.h"

#include "hal.h"

#define PSC_MAX 65535u

bool stm32_tim_period(uint32_t clock_hz, uint32_t rate_hz, uint32_t arr_max,
                      stm32_tim_period_t *out)
{
    if (rate_hz == 0u || clock_hz % rate_hz != 0u) {
        return false;
    }
    uint32_t ticks = clock_hz / rate_hz; /* (psc + 1) (arr + 1) */
    for (uint32_t div = 1u; div <= PSC_MAX + 1u && div <= ticks; div++) {
        if (ticks % div == 0u && ticks / div - 1u <= arr_max && ticks / div >= 2u) {
            out->psc = div - 1u;
            out->arr = ticks / div - 1u;
            return true;
        }
    }
    return false;
}

int stm32_tick_init(stm32_tim_t *tim, uint32_t clock_hz, uint32_t rate_hz, uint32_t arr_max)
{
    stm32_tim_period_t p;
    if (!stm32_tim_period(clock_hz, rate_hz, arr_max, &p)) {
        return HAL_ERR_RANGE;
    }
    STM32_WR(tim->CR1, STM32_TIM_CR1_URS | STM32_TIM_CR1_ARPE); /* stopped */
    STM32_WR(tim->DIER, 0u);
    STM32_WR(tim->PSC, p.psc);
    STM32_WR(tim->ARR, p.arr);
    STM32_WR(tim->CR2, STM32_TIM_CR2_MMS_UPDATE);
    /* PSC is preloaded: a software update event loads it now (with URS set
     * it raises no update flag, so no tick comes from configuring). */
    STM32_WR(tim->EGR, STM32_TIM_EGR_UG);
    STM32_WR(tim->SR, 0u);
    STM32_WR(tim->CNT, 0u);
    STM32_WR(tim->DIER, STM32_TIM_DIER_UIE);
    return HAL_OK;
}

void stm32_tick_start(stm32_tim_t *tim)
{
    STM32_SET(tim->CR1, STM32_TIM_CR1_CEN);
}

void stm32_tick_stop(stm32_tim_t *tim)
{
    STM32_CLR(tim->CR1, STM32_TIM_CR1_CEN);
}

bool stm32_tick_ack(stm32_tim_t *tim)
{
    if ((STM32_RD(tim->SR) & STM32_TIM_SR_UIF) == 0u) {
        return false;
    }
    /* rc_w0: writing 0 clears UIF, the 1s leave the other flags alone. */
    STM32_WR(tim->SR, ~STM32_TIM_SR_UIF);
    return true;
}

void stm32_encoder_init(stm32_encoder_t *enc, const stm32_encoder_config_t *cfg)
{
    stm32_tim_t *tim = cfg->tim;
    enc->cfg = *cfg;
    uint32_t filter = cfg->filter & 0xFu;
    STM32_WR(tim->CR1, 0u);
    STM32_WR(tim->SMCR, STM32_TIM_SMCR_SMS_ENCODER3);
    STM32_WR(tim->CCMR1, STM32_TIM_CCMR1_CC1S_TI1 | (filter << STM32_TIM_CCMR1_IC1F_POS) |
                             STM32_TIM_CCMR1_CC2S_TI2 | (filter << STM32_TIM_CCMR1_IC2F_POS));
    STM32_WR(tim->CCER, STM32_TIM_CCER_CC1E | STM32_TIM_CCER_CC2E |
                            (cfg->invert ? STM32_TIM_CCER_CC1P : 0u));
    STM32_WR(tim->ARR, cfg->counter_bits == 32u ? 0xFFFFFFFFu : 0xFFFFu);
    STM32_WR(tim->CNT, 0u);
    STM32_WR(tim->CR1, STM32_TIM_CR1_CEN);
    enc->last_cnt = 0u;
    enc->counts = 0u;
}

uint32_t stm32_encoder_counts(stm32_encoder_t *enc)
{
    uint32_t cnt = STM32_RD(enc->cfg.tim->CNT);
    if (enc->cfg.counter_bits == 32u) {
        enc->counts = cnt;
    } else {
        /* Signed 16-bit difference: the counter wrapped at most once. */
        int16_t delta = (int16_t)(uint16_t)((cnt - enc->last_cnt) & 0xFFFFu);
        enc->counts += (uint32_t)(int32_t)delta;
    }
    enc->last_cnt = cnt;
    return enc->counts;
}
