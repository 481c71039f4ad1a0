/* hd_kf_readout: read-out (amplitudes, states, covariance in model
 * coordinates) and angle-referenced profiles, outside the 1 kHz path. */
#include <math.h> /* sqrtf, atan2f: read-out only */
#include <stddef.h>

#include "hd_kf_internal.h"
#include "hd_trig.h"

#define PROFILE_MAX_ORDER 255.0f

/* ===================================================================== */
/* Read-out                                                               */
/* ===================================================================== */

/* Layout state (x index) of active state i (enabled blocks in
 * configuration order, offset last), or -1 outside the active states. */
static int layout_state(const hd_kf_t *kf, unsigned i)
{
    if (i >= kf->n_states) {
        return -1;
    }
    for (unsigned s = 0; s < kf->n_blocks; s++) {
        if (kf->slot[s].enabled) {
            if (i < 2u) {
                return (int)(2u * s + i);
            }
            i -= 2u;
        }
    }
    return (int)kf->offset_slot;
}

static bool block_enabled(const hd_kf_t *kf, unsigned block)
{
    return block < kf->n_blocks && kf->slot[block].enabled;
}

/* Layout state l in the model's coordinates: R(phi_s) turns the frame. */
static float model_state(const hd_kf_t *kf, unsigned l)
{
    if (l == kf->offset_slot) {
        return kf->x[l];
    }
    const unsigned f = kf->slot[l / 2u].frame;
    const float c = kf->phasor_cos[f], sn = kf->phasor_sin[f];
    const float a = kf->x[l & ~1u], b = kf->x[l | 1u];
    return (l & 1u) == 0u ? c * a + sn * b : c * b - sn * a;
}

float hd_kf_block_amplitude_nm(const hd_kf_t *kf, unsigned block)
{
    if (!block_enabled(kf, block)) {
        return 0.0f;
    }
    const float a = model_state(kf, 2u * block), b = model_state(kf, 2u * block + 1u);
    return sqrtf(a * a + b * b);
}

float hd_kf_block_row(const hd_kf_t *kf, unsigned block)
{
    if (!block_enabled(kf, block) || (kf->frozen_mask & (1u << block)) != 0u) {
        return 0.0f;
    }
    const unsigned lock = kf->slot[block].lock;
    return lock == HD_KF_LOCK_MOTOR                      ? kf->load_scale
           : lock == HD_KF_LOCK_OUTPUT && kf->output_follow &&
                   (kf->follow_slots & (1u << block)) != 0u
               ? kf->output_row
                                                           : 1.0f;
}

unsigned hd_kf_state_count(const hd_kf_t *kf)
{
    return kf->n_states;
}

float hd_kf_state(const hd_kf_t *kf, unsigned i)
{
    const int l = layout_state(kf, i);
    return l < 0 ? 0.0f : model_state(kf, (unsigned)l);
}

void hd_kf_block_amplitude_phase(const hd_kf_t *kf, unsigned block,
                                 float *amplitude_nm, float *phase_rad)
{
    *amplitude_nm = 0.0f;
    *phase_rad = 0.0f;
    if (block_enabled(kf, block) && (kf->frozen_mask & (1u << block)) == 0u) {
        const float a = model_state(kf, 2u * block), b = model_state(kf, 2u * block + 1u);
        *amplitude_nm = sqrtf(a * a + b * b);
        /* ripple = A cos(phase): x1 = A cos(phase), x2 = -A sin(phase) */
        *phase_rad = atan2f(-b, a);
    }
}

/* A block's covariance tile in model coordinates, R T R' (R = its frame),
 * by the double angle: [a b; b d] -> out[0..2] = a', b', d'. */
static void model_diag_tile(float c, float s, const float *t, float *out)
{
    const float c2 = c * c - s * s, s2 = 2.0f * s * c;
    const float mid = (t[0] + t[2]) * 0.5f, half = (t[0] - t[2]) * 0.5f;
    const float turn = half * c2 + t[1] * s2;
    out[0] = mid + turn;
    out[1] = t[1] * c2 - half * s2;
    out[2] = mid - turn;
}

float hd_kf_cov(const hd_kf_t *kf, unsigned i_active, unsigned j_active)
{
    const int li = layout_state(kf, i_active), lj = layout_state(kf, j_active);
    if (li < 0 || lj < 0) {
        return 0.0f;
    }
    unsigned i = (unsigned)li, j = (unsigned)lj;
    if (i > j) {
        const unsigned t = i;
        i = j;
        j = t;
    }
    const float *t = &kf->p[packed_index(kf->n_blocks, i & ~1u, j & ~1u)];
    const bool i_off = i == kf->offset_slot;
    const bool j_off = j == kf->offset_slot;
    if (i_off) {
        return t[0];
    }
    const unsigned si = i / 2u, sj = j / 2u;
    const float ci = kf->phasor_cos[kf->slot[si].frame];
    const float s_i = kf->phasor_sin[kf->slot[si].frame];
    if (j_off) {
        /* R_s v: the offset column of block si */
        return (i & 1u) == 0u ? ci * t[0] + s_i * t[1] : ci * t[1] - s_i * t[0];
    }
    if (si == sj) {
        float model[3];
        model_diag_tile(ci, s_i, t, model);
        return model[(i & 1u) + (j & 1u)];
    }
    /* R_si T R_sj' */
    const float cj = kf->phasor_cos[kf->slot[sj].frame];
    const float s_j = kf->phasor_sin[kf->slot[sj].frame];
    const unsigned r = i & 1u, c = j & 1u;
    const float row0 = r == 0u ? ci * t[0] + s_i * t[2] : ci * t[2] - s_i * t[0];
    const float row1 = r == 0u ? ci * t[1] + s_i * t[3] : ci * t[3] - s_i * t[1];
    return c == 0u ? row0 * cj + row1 * s_j : row1 * cj - row0 * s_j;
}

/* ===================================================================== */
/* Angle-referenced profiles                                              */
/* ===================================================================== */

static bool angle_ok(float a)
{
    return is_finite(a) && a >= 0.0f && a < HD_TWO_PI_F;
}

/* The block's order if it can be part of a profile (enabled, motor- or
 * output-locked, integral, 1..255), else 0. */
static unsigned profile_order(const hd_kf_slot_t *sl)
{
    const float k = sl->theta_per_unit;
    if (!sl->enabled || sl->lock == HD_KF_LOCK_FIXED || !(k >= 1.0f && k <= PROFILE_MAX_ORDER) ||
        k != (float)(unsigned)k) {
        return 0u;
    }
    return (unsigned)k;
}

/* cos and sin of k alpha, alpha = the lock angle of the sample the state
 * is at (the caller's: the sample of the most recent step). */
static void profile_rotation(const hd_kf_slot_t *sl, unsigned k, float motor_angle_rad,
                             float output_angle_rad, float *c, float *s)
{
    const float alpha = sl->lock == HD_KF_LOCK_MOTOR ? motor_angle_rad : output_angle_rad;
    hd_sincosf((float)k * alpha, s, c);
}

int hd_kf_profile_export(const hd_kf_t *kf, float motor_angle_rad, float output_angle_rad,
                         hd_kf_profile_t *profile)
{
    if (kf == NULL || profile == NULL) {
        return HD_KF_ERR_NULL;
    }
    if (!angle_ok(motor_angle_rad) || !angle_ok(output_angle_rad)) {
        return HD_KF_ERR_ANGLE;
    }
    unsigned n = 0;
    for (unsigned s = 0; s < kf->n_blocks; s++) {
        const hd_kf_slot_t *sl = &kf->slot[s];
        const unsigned k = profile_order(sl);
        if (k == 0u) {
            continue;
        }
        float c, sn;
        profile_rotation(sl, k, motor_angle_rad, output_angle_rad, &c, &sn);
        /* (a, b) = R(k alpha)' x, x in the model's coordinates */
        const float x1 = model_state(kf, 2u * s), x2 = model_state(kf, 2u * s + 1u);
        hd_kf_profile_line_t *line = &profile->lines[n++];
        line->lock = sl->lock;
        line->order = (uint8_t)k;
        line->a_nm = c * x1 - sn * x2;
        line->b_nm = sn * x1 + c * x2;
    }
    profile->line_count = (uint8_t)n;
    profile->load_nm = kf->learn_load_weight > 0.0f ? kf->learn_load_nm / kf->learn_load_weight
                                                    : -1.0f;
    return (int)n;
}

static hd_kf_err_t check_profile(const hd_kf_t *kf, const hd_kf_profile_t *profile,
                                 float motor_angle_rad, float output_angle_rad,
                                 float prior_var_nm2)
{
    if (kf == NULL || profile == NULL) {
        return HD_KF_ERR_NULL;
    }
    if (!angle_ok(motor_angle_rad) || !angle_ok(output_angle_rad)) {
        return HD_KF_ERR_ANGLE;
    }
    if (profile->line_count > HD_KF_MAX_BLOCKS || !is_nonneg(prior_var_nm2) ||
        prior_var_nm2 > kf->cfg.p_max_nm2 || profile->load_nm > HD_KF_MAX_ABS_Y_NM) {
        return HD_KF_ERR_PROFILE;
    }
    for (unsigned i = 0; i < profile->line_count; i++) {
        const hd_kf_profile_line_t *line = &profile->lines[i];
        if ((line->lock != HD_KF_LOCK_MOTOR && line->lock != HD_KF_LOCK_OUTPUT) ||
            line->order == 0u || !is_finite(line->a_nm) || !is_finite(line->b_nm)) {
            return HD_KF_ERR_PROFILE;
        }
    }
    return HD_KF_OK;
}

/* Block s takes (a, b): its state in its frame and a fresh covariance
 * block v I, decorrelated. */
static void set_block(hd_kf_t *kf, unsigned s, float x1, float x2, float var_nm2)
{
    hd_kf_clear_block(kf, s, var_nm2);
    const unsigned f = kf->slot[s].frame;
    const float c = kf->phasor_cos[f], sn = kf->phasor_sin[f];
    /* the frame's R' takes the model's coordinates into the frame */
    kf->x[2u * s] = c * x1 - sn * x2;
    kf->x[2u * s + 1u] = sn * x1 + c * x2;
    keep_block_state(kf, s);
}

int hd_kf_profile_import(hd_kf_t *kf, const hd_kf_profile_t *profile, float motor_angle_rad,
                         float output_angle_rad, float prior_var_nm2)
{
    const hd_kf_err_t err =
        check_profile(kf, profile, motor_angle_rad, output_angle_rad, prior_var_nm2);
    if (err != HD_KF_OK) {
        return err;
    }
    uint32_t matched = 0u;
    int count = 0;
    for (unsigned i = 0; i < profile->line_count; i++) {
        const hd_kf_profile_line_t *line = &profile->lines[i];
        for (unsigned s = 0; s < kf->n_blocks; s++) {
            const hd_kf_slot_t *sl = &kf->slot[s];
            if ((matched & (1u << s)) != 0u || sl->lock != line->lock ||
                profile_order(sl) != line->order) {
                continue;
            }
            float c, sn;
            profile_rotation(sl, line->order, motor_angle_rad, output_angle_rad, &c, &sn);
            /* x = R(k alpha) (a, b)' in the model's coordinates */
            set_block(kf, s, c * line->a_nm + sn * line->b_nm, c * line->b_nm - sn * line->a_nm,
                      prior_var_nm2);
            matched |= 1u << s;
            count++;
            break;
        }
    }
    /* the held output rows' reference: the motor blocks as imported */
    for (unsigned s = 0; s < kf->n_blocks; s++) {
        const bool ref = (matched & kf->motor_slots & (1u << s)) != 0u;
        kf->motor_ref[2u * s] = ref ? kf->x[2u * s] : 0.0f;
        kf->motor_ref[2u * s + 1u] = ref ? kf->x[2u * s + 1u] : 0.0f;
    }
    kf->follow_slots = matched & kf->output_slots;
    kf->follow_load_nm = is_finite(profile->load_nm) ? profile->load_nm : -1.0f;
    hd_kf_follow_reference(kf);
    hd_kf_follow_restart(kf);
    hd_kf_profile_motion(kf, matched);
    return count;
}
