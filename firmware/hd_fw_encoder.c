/* hd_fw_encoder: the encoder tracker stage (hd_fw_stages.h).
 *
 * Contract: one call per tick, after the gauge.  Reads the encoders once;
 * fills the sample's counts and its motor and output increments (glitches
 * and failed reads replaced by the last good increment: the motion is
 * assumed to continue), and advances the absolute positions the profiles
 * refer to.  Without an output encoder the output increment is the motor's
 * over the gear ratio.  Returns HD_FAULT_ENC_FAULT / HD_FAULT_ENC_GLITCH. */
#include <string.h>

#include "hd_fw.h"
#include "hd_fw_internal.h"
#include "hd_trig.h"

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
static void track_positions(hd_fw_encoder_t *k, const hd_fw_settings_t *set, bool good,
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

/* No usable counts: assume the previous motion continues. */
static void hold_motion(hd_fw_encoder_t *k, hal_encoder_sample_t *enc, int32_t *dm,
                        int32_t *dout)
{
    *dm = k->last_good_motor_delta;
    *dout = k->last_good_output_delta;
    k->prev_motor_counts += (uint32_t)*dm;
    k->prev_output_counts += (uint32_t)*dout;
    enc->has_output = k->output_present;
    enc->motor_counts = k->prev_motor_counts;
    enc->output_counts = k->prev_output_counts;
}

uint32_t hd_fw_encoder(hd_fw_encoder_t *k, const hd_fw_settings_t *set, const hal_sensors_t *sen,
                       hd_fw_sample_t *s)
{
    hal_encoder_sample_t enc;
    memset(&enc, 0, sizeof enc);
    int rc = (sen->encoder_read != NULL) ? sen->encoder_read(sen->ctx, &enc) : HAL_ERR_NO_DATA;
    uint32_t faults = 0u;
    int32_t dm = 0;
    int32_t dout = 0;
    if (rc != HAL_OK || enc.fault) {
        faults |= HD_FAULT_ENC_FAULT;
        hold_motion(k, &enc, &dm, &dout);
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

static float angle_of(uint32_t pos, float rad_per_count)
{
    const float a = (float)pos * rad_per_count;
    return a < HD_TWO_PI_F ? a : 0.0f; /* (cpr - 1) / cpr can round up to 2 pi */
}

float hd_fw_encoder_motor_rad(const hd_fw_encoder_t *k, const hd_fw_settings_t *set)
{
    return angle_of(k->motor_pos, set->motor_rad_per_count);
}

float hd_fw_encoder_output_rad(const hd_fw_encoder_t *k, const hd_fw_settings_t *set)
{
    return angle_of(k->output_pos, set->output_rad_per_count);
}
