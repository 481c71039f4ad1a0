/* hd_kf_rows: the load-dependent measurement rows the step uses (hd_kf.h:
 * ripple_load_coeff_per_nm for motor-locked rows, output_row_follow for the
 * held output rows; docs/design/filter.md, "Load-modulated output lines"),
 * called by hd_kf_step only when one of them is on; and the load the motor
 * blocks learn at (the profile's load_nm), on every step they learn fully. */
#include <math.h> /* fabsf, sqrtf (VSQRT on Cortex-M4F) */

#include "hd_kf_internal.h"

/* The motion fraction min(1, |angle| / q_motion_ref_rad); 1 when off. */
static float motion_fraction(const hd_kf_t *kf, float angle_rad)
{
    const float a = fabsf(angle_rad);
    return (kf->q_motion_inv_rad <= 0.0f || a >= kf->cfg.q_motion_ref_rad)
               ? 1.0f
               : a * kf->q_motion_inv_rad;
}

/* T_exp (+ the offset when it is real torque and primed): the torque the
 * load-dependent rows scale with. */
static float torque_now(const hd_kf_t *kf, float torque_expected_nm)
{
    float t_now = is_finite(torque_expected_nm) ? torque_expected_nm : 0.0f;
    if (kf->cfg.offset_enabled && !kf->cfg.offset_is_sensor_error && kf->offset_primed) {
        t_now += kf->x[kf->offset_slot];
    }
    return t_now;
}

static float capped_abs(float t_nm)
{
    const float t = fabsf(t_nm);
    return t < HD_KF_MAX_ABS_Y_NM ? t : HD_KF_MAX_ABS_Y_NM;
}

/* |T_ref| of the load-dependent rows: T_ref starts at T_exp (+ the offset
 * when it is real torque and primed) and follows it by the motor's motion
 * fraction, held at standstill; capped at HD_KF_MAX_ABS_Y_NM so every row
 * stays finite. */
float hd_kf_load_ref(hd_kf_t *kf, float torque_expected_nm, float d_motor_rad)
{
    const float t_now = torque_now(kf, torque_expected_nm);
    if (!kf->load_ref_primed) {
        kf->load_ref_nm = t_now;
        kf->load_ref_primed = 1u;
    } else {
        kf->load_ref_nm += motion_fraction(kf, d_motor_rad) * (t_now - kf->load_ref_nm);
    }
    return capped_abs(kf->load_ref_nm);
}

/* The load the motor blocks learn at: |T_now| exponentially weighted over
 * the steps at which they learn at full motion (memory
 * HD_KF_FOLLOW_MEMORY_S), kept unnormalized with its filled weight (no
 * division per step); export's load_nm is their ratio. */
void hd_kf_learn_load(hd_kf_t *kf, float torque_expected_nm)
{
    const float a = kf->cfg.ts_s * (1.0f / HD_KF_FOLLOW_MEMORY_S);
    const float t = capped_abs(torque_now(kf, torque_expected_nm));
    kf->learn_load_weight += a * (1.0f - kf->learn_load_weight);
    kf->learn_load_nm += a * (t - kf->learn_load_nm);
}

/* The growth's regression, fitted once per step: its mean, its slope once
 * HD_KF_FOLLOW_MIN_WEIGHT of its weight is filled (about that times
 * HD_KF_FOLLOW_MEMORY_S of measured steps) and |T_ref| has spread (0
 * before), and the span of |T_ref| it may be read at: two standard
 * deviations either side of the mean, no extrapolation from a short,
 * narrow fit. */
typedef struct {
    float mean_t, mean_g, slope, span;
} follow_fit_t;

static follow_fit_t follow_fit(const hd_kf_t *kf)
{
    follow_fit_t f = {kf->follow_mean_t, kf->follow_mean_g, 0.0f, 0.0f};
    if (kf->follow_weight >= HD_KF_FOLLOW_MIN_WEIGHT && kf->follow_var_t > HD_KF_FOLLOW_MIN_VAR_NM2) {
        f.span = 2.0f * sqrtf(kf->follow_var_t);
        f.slope = kf->follow_cov_tg / kf->follow_var_t;
    }
    return f;
}

/* The regression at |T_ref| = t. */
static float follow_predict(const follow_fit_t *f, float t)
{
    float dt = t - f->mean_t;
    dt = dt > f->span ? f->span : (dt < -f->span ? -f->span : dt);
    return f->mean_g + f->slope * dt;
}

/* The held output blocks' row (output_follow).  The growth g of the motor
 * lines since the profile import, sqrt(sum |x|^2 / sum |ref|^2) over the
 * imported motor blocks (1 as imported, (1 + c |T|) / (1 + c |T_c|) for
 * lines grown by a common load factor), is measured while `observed` (every
 * motor block turning at least HD_KF_FOLLOW_MIN_RAD per step, none frozen;
 * not in the first HD_KF_FOLLOW_SETTLE_S after the import, while the motor
 * blocks settle) and feeds an exponentially weighted regression of g on
 * |T_ref| (1 before its first sample).  The row's target is the growth the load explains: the
 * regression at |T_ref| over the regression at the profile's load T_c
 * (lines changed at a constant load, by wear or temperature, give the same
 * g at both and do not move the row), times (1 + c |T_ref|) / (1 + c T_c)
 * with a model load coefficient c (ripple_load_coeff_per_nm: the motor rows
 * carry that factor, their states stay at zero load), refused beyond
 * [1 / max, max] (held at the bound: HD_KF_STATUS_LOAD_BOUND) and
 * low-passed into output_row.  Without imported motor lines only the
 * modelled factor moves the row (g measured stays 1).  T_c unknown (a
 * version-1 record, a CAN upload: drift and load cannot be told apart), or
 * neither a reference nor a coefficient: 1. */
uint32_t hd_kf_follow_motor_lines(hd_kf_t *kf, float t_abs, bool observed)
{
    const float c = kf->cfg.ripple_load_coeff_per_nm;
    if (kf->follow_load_nm < 0.0f || (kf->motor_ref_inv <= 0.0f && !(c > 0.0f))) {
        kf->output_row = 1.0f;
        return 0u;
    }
    if (kf->motor_ref_inv <= 0.0f) {
        observed = false; /* no imported motor line to measure a growth against */
    }
    if (kf->follow_settle_steps != 0u) {
        kf->follow_settle_steps--; /* the motor blocks still settle on the joint as it is now */
        observed = false;
    }
    if (observed) {
        float sq = 0.0f;
        for (uint32_t left = kf->motor_slots; left != 0u; left &= left - 1u) {
            const unsigned s = (unsigned)__builtin_ctz(left);
            const float w = (kf->motor_ref[2u * s] != 0.0f || kf->motor_ref[2u * s + 1u] != 0.0f)
                                ? 1.0f : 0.0f;
            sq += w * (kf->x[2u * s] * kf->x[2u * s] + kf->x[2u * s + 1u] * kf->x[2u * s + 1u]);
        }
        const float g = sqrtf(sq * kf->motor_ref_inv);
        if (!kf->follow_primed) {
            kf->follow_mean_t = t_abs;
            kf->follow_mean_g = g;
            kf->follow_primed = 1u;
        } else {
            const float a = kf->cfg.ts_s * (1.0f / HD_KF_FOLLOW_MEMORY_S);
            const float dt = t_abs - kf->follow_mean_t, dg = g - kf->follow_mean_g;
            kf->follow_mean_t += a * dt;
            kf->follow_mean_g += a * dg;
            kf->follow_var_t = (1.0f - a) * (kf->follow_var_t + a * dt * dt);
            kf->follow_weight += a * (1.0f - kf->follow_weight);
            kf->follow_cov_tg = (1.0f - a) * (kf->follow_cov_tg + a * dt * dg);
        }
    }
    float g = 1.0f;
    if (kf->follow_primed) {
        const follow_fit_t fit = follow_fit(kf); /* one fit, read at both loads */
        const float g_c = follow_predict(&fit, kf->follow_load_nm);
        g = g_c > 0.0f ? follow_predict(&fit, t_abs) / g_c : 1.0f;
    }
    if (c > 0.0f) {
        /* the motor rows already carry the modelled factor (their states are
         * zero-load lines): the output lines take it too, from T_c */
        g *= (1.0f + c * t_abs) / (1.0f + c * kf->follow_load_nm);
    }
    const float hi = kf->cfg.output_row_max, lo = 1.0f / hi;
    float target = 1.0f + kf->cfg.output_row_follow * (g - 1.0f);
    uint32_t status = 0u;
    if (!(target >= lo && target <= hi)) {
        target = target > hi ? hi : lo; /* NaN: the lower bound */
        status = HD_KF_STATUS_LOAD_BOUND;
        kf->load_bound_count++;
    }
    kf->output_row += kf->output_row_alpha * (target - kf->output_row);
    return status;
}
