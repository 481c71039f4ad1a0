/* hd_fw_sense: the tick's sensor step (ADC -> N m, encoder deltas and
 * positions, motor current) and the slow-torque inputs of its pipeline step
 * (feed-forward with its staleness, the current-based torque).  Tick
 * context only: see hd_fw_tick.c. */
#include <math.h> /* isfinite, NAN: compiler builtins, no libm call */
#include <string.h>

#include "hd_fw.h"
#include "hd_fw_internal.h"

/* ----------------------------------------------------------------- sense */

static int32_t abs32(int32_t v)
{
    return v < 0 ? (v == INT32_MIN ? INT32_MAX : -v) : v;
}

/* One encoder channel: the wrapped count delta, with glitch rejection. */
static int32_t encoder_delta(uint32_t counts, uint32_t *prev, int32_t *last_good, int32_t max_delta,
                             bool *glitch)
{
    int32_t d = (int32_t)(counts - *prev); /* modulo 2^32: wraps are fine */
    *prev = counts; /* track the raw count so a one-sample spike costs no angle */
    if (abs32(d) > max_delta) {
        *glitch = true;
        return *last_good;
    }
    *last_good = d;
    return d;
}

/* (pos + d) modulo cpr; |d| is below the glitch limit (<= 1e9) and
 * pos < cpr <= 2^24, so the sum fits an int32. */
static uint32_t wrap_pos(uint32_t pos, int32_t d, uint32_t cpr)
{
    int32_t r = ((int32_t)pos + d) % (int32_t)cpr;
    return (uint32_t)(r < 0 ? r + (int32_t)cpr : r);
}

/* The absolute angles the profiles refer to: the first good reading modulo
 * cpr, then every increment the filter is given (glitch replacements
 * included, so they follow the filter's own phase). */
static void track_positions(hd_fw_tick_state_t *k, const hd_fw_settings_t *set, bool good,
                            const hal_encoder_sample_t *enc, int32_t dm, int32_t dout)
{
    const uint32_t mcpr = set->cfg.motor_cpr;
    const uint32_t ocpr = set->cfg.output_cpr;
    if (k->pos_valid && (mcpr != k->pos_motor_cpr || ocpr != k->pos_output_cpr)) {
        k->pos_valid = false; /* counted in other units: start again from a reading */
    }
    if (!k->pos_valid) {
        if (!good) {
            return;
        }
        k->pos_valid = true;
        k->pos_motor_cpr = mcpr;
        k->pos_output_cpr = ocpr;
        k->motor_pos = enc->motor_counts % mcpr;
        k->output_pos_valid = enc->has_output;
        k->output_pos = enc->has_output ? enc->output_counts % ocpr : 0u;
        return;
    }
    k->motor_pos = wrap_pos(k->motor_pos, dm, mcpr);
    if (!enc->has_output) {
        k->output_pos_valid = false;
    } else if (k->output_pos_valid) {
        k->output_pos = wrap_pos(k->output_pos, dout, ocpr);
    } else if (good) {
        /* the output encoder (back): its counts are absolute */
        k->output_pos_valid = true;
        k->output_pos = enc->output_counts % ocpr;
    }
}

static uint32_t read_encoders(hd_fw_t *fw, hd_fw_sample_t *s)
{
    const hd_fw_settings_t *set = hd_fw_live(fw);
    const hal_sensors_t *sen = &fw->hal->sensors;
    hd_fw_tick_state_t *k = &fw->tick;
    hal_encoder_sample_t enc;
    memset(&enc, 0, sizeof enc);
    int rc = (sen->encoder_read != NULL) ? sen->encoder_read(sen->ctx, &enc) : HAL_ERR_NO_DATA;
    uint32_t faults = 0u;
    int32_t dm = 0;
    int32_t dout = 0;
    if (rc != HAL_OK || enc.fault) {
        /* No usable counts: assume the previous motion continues. */
        faults |= HD_FAULT_ENC_FAULT;
        dm = k->last_good_motor_delta;
        dout = k->last_good_output_delta;
        k->prev_motor_counts += (uint32_t)dm;
        k->prev_output_counts += (uint32_t)dout;
        enc.has_output = k->output_present;
        enc.motor_counts = k->prev_motor_counts;
        enc.output_counts = k->prev_output_counts;
    } else if (!k->have_prev) {
        k->have_prev = true;
        k->prev_motor_counts = enc.motor_counts;
        k->prev_output_counts = enc.output_counts;
        k->output_present = enc.has_output;
    } else {
        bool glitch = false;
        k->output_present = enc.has_output;
        dm = encoder_delta(enc.motor_counts, &k->prev_motor_counts, &k->last_good_motor_delta,
                           set->max_motor_delta_counts, &glitch);
        if (enc.has_output) {
            dout = encoder_delta(enc.output_counts, &k->prev_output_counts,
                                 &k->last_good_output_delta, set->max_output_delta_counts, &glitch);
        }
        if (glitch) {
            faults |= HD_FAULT_ENC_GLITCH;
        }
    }
    track_positions(k, set, rc == HAL_OK && !enc.fault, &enc, dm, dout);
    s->motor_counts = enc.motor_counts;
    s->output_counts = enc.output_counts;
    s->has_output = enc.has_output;
    s->d_motor_angle_rad = (float)dm * set->motor_rad_per_count;
    s->d_output_angle_rad = enc.has_output ? (float)dout * set->output_rad_per_count
                                           : s->d_motor_angle_rad / set->cfg.gear_ratio;
    return faults;
}

static uint32_t read_torque(const hd_fw_t *fw, int adc_rc, const hal_adc_sample_t *adc,
                            hd_fw_sample_t *s)
{
    const hd_fw_config_t *c = &hd_fw_live(fw)->cfg;
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

static void remember_for_tare(hd_fw_tick_state_t *k, float bridge_v)
{
    k->tare_v[k->tare_next] = bridge_v;
    k->tare_next = (k->tare_next + 1u) % HD_FW_TARE_TICKS;
    if (k->tare_n < HD_FW_TARE_TICKS) {
        k->tare_n = k->tare_n + 1u;
    }
}

/* The optional motor-current channel.  A failed or non-finite reading
 * holds the last good value; it is a fault only when T_exp uses it. */
static uint32_t read_current(hd_fw_t *fw, hd_fw_sample_t *s)
{
    const hal_sensors_t *sen = &fw->hal->sensors;
    hd_fw_tick_state_t *k = &fw->tick;
    s->motor_current_a = NAN;
    if (sen->current_read == NULL) {
        return 0u;
    }
    hal_current_sample_t cur;
    memset(&cur, 0, sizeof cur);
    const int rc = sen->current_read(sen->ctx, &cur);
    const bool good = rc == HAL_OK && !cur.fault && isfinite(cur.motor_current_a);
    if (good) {
        k->current_a = cur.motor_current_a;
    }
    s->motor_current_a = k->current_a;
    return (!good && hd_fw_live(fw)->cfg.current.nm_per_a > 0.0f) ? HD_FAULT_CURRENT_ERROR : 0u;
}

/* ADC and encoders into *s; returns the sensor faults.  *ended: the sample
 * source is exhausted (replay, simulation end). */
uint32_t hd_fw_sense(hd_fw_t *fw, uint64_t t_us, hd_fw_sample_t *s, bool *ended)
{
    const hal_t *hal = fw->hal;
    hal_adc_sample_t adc;
    memset(&adc, 0, sizeof adc);
    memset(s, 0, sizeof *s);
    s->t_us = t_us;
    int adc_rc = hal->sensors.adc_read(hal->sensors.ctx, &adc);
    *ended = adc_rc == HAL_ERR_END;
    if (*ended) {
        return 0u;
    }
    uint32_t faults = read_torque(fw, adc_rc, &adc, s);
    s->valid = faults == 0u;
    if (s->valid) {
        remember_for_tare(&fw->tick, s->bridge_v);
    }
    faults |= read_encoders(fw, s);
    return faults | read_current(fw, s);
}

/* ----------------------------------------------------------- slow torque */

/* The feed-forward in T_exp: the latched value while fresh; once older than
 * the timeout, FF_STALE and a ramp to zero over feedforward_ramp_ms from the
 * last value (docs/design/slow-torque.md, "Feed-forward"). */
float hd_fw_feedforward_nm(hd_fw_t *fw, uint32_t *faults)
{
    const hd_fw_config_t *c = &hd_fw_live(fw)->cfg;
    hd_fw_tick_state_t *k = &fw->tick;
    if (c->feedforward_timeout_ms == 0u) {
        return 0.0f;
    }
    if (k->ff_have && k->ff_age_ticks <= c->feedforward_timeout_ms) {
        k->ff_stale_ticks = 0u;
        return k->ff_nm;
    }
    *faults |= HD_FAULT_FF_STALE;
    if (k->ff_stale_ticks < UINT32_MAX) {
        k->ff_stale_ticks++;
    }
    const uint32_t ramp = c->feedforward_ramp_ms;
    if (k->ff_stale_ticks >= ramp) {
        return 0.0f;
    }
    /* ff_nm is the last fresh value: a frame makes it fresh again */
    return k->ff_nm * (1.0f - (float)k->ff_stale_ticks / (float)ramp);
}

/* T_cur of hd_expected.h on inputs low-passed alike: the current, the
 * output velocity (from the motor increments: 1/gear ratio finer than the
 * output encoder) and the derivative of the filtered velocity, through the
 * same two first-order stages.  T_exp is the slow torque: unfiltered, the
 * drive's current noise (N kt times tens of mA) and the rotor's inertia
 * torque against a lagging acceleration estimate would enter the filter's
 * innovation (docs/design/slow-torque.md, "Motor current"). */
float hd_fw_current_torque_nm(hd_fw_t *fw, const hd_pipeline_t *p, const hd_fw_sample_t *s,
                              float *var_nm2)
{
    const hd_fw_settings_t *set = hd_fw_live(fw);
    const hd_fw_config_t *c = &set->cfg;
    hd_fw_tick_state_t *k = &fw->tick;
    *var_nm2 = 0.0f;
    if (!(c->current.nm_per_a > 0.0f) || !isfinite(s->motor_current_a)) {
        k->cur_primed = false;
        return 0.0f;
    }
    const float a = set->current_alpha;
    const float w = s->d_motor_angle_rad / (c->gear_ratio * HD_FW_TS_S);
    const bool first = !k->cur_primed;
    float acc = 0.0f;
    if (first) {
        k->cur_i1 = k->cur_i2 = s->motor_current_a;
        k->cur_w1 = k->cur_w2 = w;
        k->cur_primed = true;
    } else {
        k->cur_i1 += a * (s->motor_current_a - k->cur_i1);
        k->cur_i2 += a * (k->cur_i1 - k->cur_i2);
        k->cur_w1 += a * (w - k->cur_w1);
        const float dw = a * (k->cur_w1 - k->cur_w2);
        k->cur_w2 += dw;
        acc = dw / HD_FW_TS_S;
    }
    const float t = hd_expected_current_nm(&c->current, &p->expected, k->cur_i2, k->cur_w2,
                                           acc);
    /* The low-pass lags a changing torque by lag x its change per tick:
     * that much of T_exp is wrong while it changes (starts, stops, payload
     * steps), and the filter is told so instead of learning it as ripple
     * (docs/design/slow-torque.md, "Motor current"). */
    const float lag_nm = first ? 0.0f : set->current_lag_ticks * (t - k->cur_torque_nm);
    *var_nm2 = lag_nm * lag_nm;
    k->cur_torque_nm = t;
    return t;
}
