/* hd_fw_sense: the gauge stage (hd_fw_stages.h).
 *
 * Contract: the first stage of every tick.  It reads the ADC once, stamps
 * the sample and turns the bridge counts into volts and N m
 * with the live calibration; a sample the gauge cannot vouch for (ADC
 * error, open bridge, saturated, non-finite, beyond the torque limit) is
 * invalid (torque NaN) with its fault bit.  Valid voltages enter the tare
 * window the background's TARE averages.  Returns false when the sample
 * source is exhausted (replay, simulation end): the tick stops, and the
 * sample is left as it was. */
#include <math.h> /* isfinite, NAN: compiler builtins, no libm call */
#include <string.h>

#include "hd_fw.h"
#include "hd_fw_internal.h"

static uint32_t read_torque(const hd_fw_config_t *c, int adc_rc, const hal_adc_sample_t *adc,
                            hd_fw_sample_t *s)
{
    s->bridge_counts = adc->bridge_counts;
    s->bridge_v = NAN;
    s->torque_raw_nm = NAN;
    if (adc_rc == HAL_ERR_FAULT) {
        return HD_FAULT_OPEN_BRIDGE;
    }
    if (adc_rc != HAL_OK) {
        return HD_FAULT_ADC_ERROR;
    }
    if (adc->saturated) {
        return HD_FAULT_ADC_SATURATED;
    }
    float v = (float)adc->bridge_counts * c->adc_volts_per_count;
    float t = c->calib_gain_nm_per_v * (v - c->calib_offset_v);
    s->bridge_v = v;
    if (!isfinite(t)) {
        return HD_FAULT_ADC_ERROR;
    }
    if (t > c->torque_limit_nm || t < -c->torque_limit_nm) {
        return HD_FAULT_TORQUE_RANGE;
    }
    s->torque_raw_nm = t;
    return 0u;
}

static void remember_for_tare(hd_fw_gauge_t *k, float bridge_v)
{
    k->tare_v[k->tare_next] = bridge_v;
    k->tare_next = (k->tare_next + 1u) % HD_FW_TARE_TICKS;
    if (k->tare_n < HD_FW_TARE_TICKS) {
        k->tare_n = k->tare_n + 1u;
    }
}

bool hd_fw_gauge(hd_fw_gauge_t *g, const hd_fw_config_t *c, const hal_sensors_t *sen,
                 uint64_t t_us, hd_fw_sample_t *s, uint32_t *faults)
{
    hal_adc_sample_t adc;
    memset(&adc, 0, sizeof adc);
    int adc_rc = sen->adc_read(sen->ctx, &adc);
    if (adc_rc == HAL_ERR_END) {
        return false; /* *s untouched: it is the last tick's sample */
    }
    /* No clearing of *s: the stages write every field of it each tick
     * (test_fw_isr.c poisons it to check), which saves a memset of 80 bytes */
    s->t_us = t_us;
    *faults = read_torque(c, adc_rc, &adc, s);
    s->valid = *faults == 0u;
    if (s->valid) {
        remember_for_tare(g, s->bridge_v);
    }
    return true;
}
