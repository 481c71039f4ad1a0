/* stm32f4_adc: see stm32f4_adc.h. */
#include "stm32f4_adc.h"

#define ADC_CHANNELS 16u
#define SMPR2_CHANNELS 10u  /* channels 0..9 in SMPR2, 10..18 in SMPR1 */
#define SMP_BITS 3u

int stm32_adc_init(stm32_adc_drv_t *drv, const stm32_adc_config_t *cfg)
{
    if (cfg->channel >= ADC_CHANNELS || cfg->sample_code > STM32_ADC_SMP_CODE_MAX ||
        cfg->jextsel > 0xFu || cfg->adcpre > 3u || cfg->midscale_counts > STM32_ADC_FULL_SCALE) {
        return HAL_ERR_RANGE;
    }
    drv->cfg = *cfg;
    drv->conversions = 0u;
    drv->timeouts = 0u;
    stm32_adc_t *adc = cfg->adc;
    STM32_WR(adc->CR2, 0u); /* off while configuring */
    uint32_t ccr = STM32_RD(cfg->common->CCR) & ~STM32_ADC_CCR_ADCPRE_MASK;
    STM32_WR(cfg->common->CCR, ccr | ((uint32_t)cfg->adcpre << STM32_ADC_CCR_ADCPRE_POS));
    STM32_WR(adc->CR1, 0u); /* 12 bit, no scan, no interrupts: the tick reads it */
    uint32_t ch = cfg->channel;
    if (ch < SMPR2_CHANNELS) {
        uint32_t shift = SMP_BITS * ch;
        STM32_WR(adc->SMPR2, (STM32_RD(adc->SMPR2) & ~(7u << shift)) |
                                 ((uint32_t)cfg->sample_code << shift));
    } else {
        uint32_t shift = SMP_BITS * (ch - SMPR2_CHANNELS);
        STM32_WR(adc->SMPR1, (STM32_RD(adc->SMPR1) & ~(7u << shift)) |
                                 ((uint32_t)cfg->sample_code << shift));
    }
    /* One injected conversion (JL = 0): the channel goes in JSQ4. */
    STM32_WR(adc->JSQR, ch << STM32_ADC_JSQR_JSQ4_POS);
    STM32_WR(adc->JOFR[0], cfg->midscale_counts);
    STM32_WR(adc->SR, 0u);
    STM32_WR(adc->CR2, STM32_ADC_CR2_ADON |
                           ((uint32_t)cfg->jextsel << STM32_ADC_CR2_JEXTSEL_POS) |
                           STM32_ADC_CR2_JEXTEN_RISING);
    return HAL_OK;
}

void stm32_adc_start(stm32_adc_drv_t *drv)
{
    STM32_SET(drv->cfg.adc->CR2, STM32_ADC_CR2_JSWSTART);
}

int stm32_adc_read(void *ctx, hal_adc_sample_t *out)
{
    stm32_adc_drv_t *drv = ctx;
    stm32_adc_t *adc = drv->cfg.adc;
    if (!stm32_wait(&adc->SR, STM32_ADC_SR_JEOC, STM32_ADC_SR_JEOC, drv->cfg.ready_polls)) {
        drv->timeouts++;
        return HAL_ERR_IO;
    }
    /* With an offset the right-aligned result is sign-extended to 16 bits. */
    int32_t counts = (int16_t)(uint16_t)(STM32_RD(adc->JDR[0]) & 0xFFFFu);
    STM32_WR(adc->SR, ~(STM32_ADC_SR_JEOC | STM32_ADC_SR_JSTRT)); /* rc_w0 */
    int32_t raw = counts + (int32_t)drv->cfg.midscale_counts;
    out->bridge_counts = counts;
    out->saturated = raw <= 0 || raw >= (int32_t)STM32_ADC_FULL_SCALE;
    drv->conversions++;
    return HAL_OK;
}
