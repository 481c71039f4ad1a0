/*
 * kf_step_v0: hd_kf_step as it was at commit d9ce5d9, before issue 16 (dense
 * 17 x 17 covariance rotated every step, Joseph weights for every entry,
 * three sin/cos per step, amplitudes every step).  Kept ONLY as the speed
 * baseline of the compute benchmark (bench_compute measures the current
 * hd_kf_step against it in the same run); not used anywhere else.  The
 * configuration functions are the library's (hd_kf_config_*); this copy
 * ignores output_learn_scale (it predates it: 1).
 */
#include "kf_step_v0.h"

#include <math.h>
#include <stddef.h>

#include "hd_trig.h"

#define JUMP_MIN_SIGMA 4.0f

/* isfinite without libm calls; x - x is 0 only for finite x. */
static bool is_finite(float x)
{
    return (x - x) == 0.0f;
}

static float block_p0(const v0_kf_t *kf, unsigned block)
{
    return kf->cfg.blocks[block].lock == HD_KF_LOCK_OUTPUT ? kf->cfg.output_p0_nm2
                                                          : kf->cfg.p0_nm2;
}

/* Zeroes row and column i of P and sets the diagonal to p0: the state
 * restarts with no correlation to the others (keeps P PSD). */
static void reset_state_cov(v0_kf_t *kf, unsigned i, float p0_nm2)
{
    for (unsigned j = 0; j < kf->n_states; j++) {
        kf->p[i][j] = 0.0f;
        kf->p[j][i] = 0.0f;
    }
    kf->p[i][i] = p0_nm2;
    kf->x[i] = 0.0f;
}

/* Rebuilds the active-slot tables from cfg (enabled blocks in configuration
 * order, offset last). */
static void build_layout(v0_kf_t *kf)
{
    unsigned slots = 0;
    for (unsigned i = 0; i < kf->cfg.block_count; i++) {
        if (kf->cfg.blocks[i].enabled) {
            kf->block_index[slots++] = (uint8_t)i;
        }
    }
    kf->active_blocks = (uint8_t)slots;
    kf->offset_slot = (uint8_t)(2u * slots);
    kf->n_states = (uint8_t)(2u * slots + (kf->cfg.offset_enabled ? 1u : 0u));
}

void v0_kf_reset(v0_kf_t *kf)
{
    for (unsigned i = 0; i < HD_KF_MAX_STATES; i++) {
        kf->x[i] = 0.0f;
        for (unsigned j = 0; j < HD_KF_MAX_STATES; j++) {
            kf->p[i][j] = 0.0f;
        }
    }
    for (unsigned i = 0; i < kf->n_states; i++) {
        kf->p[i][i] = kf->cfg.p0_nm2;
    }
    for (unsigned s = 0; s < kf->active_blocks; s++) {
        kf->p[2u * s][2u * s] = kf->p[2u * s + 1u][2u * s + 1u] =
            block_p0(kf, kf->block_index[s]);
    }
    kf->frozen_mask = 0u;
    kf->offset_primed = 0u;
    kf->load_ref_primed = 0u;
    kf->load_ref_nm = 0.0f;
}

/* Phase advance of a block over this step [rad]. */
static float block_theta(const hd_kf_block_config_t *b, const hd_kf_input_t *in,
                         float ts_s)
{
    switch (b->lock) {
    case HD_KF_LOCK_MOTOR: return b->order * in->d_motor_angle_rad;
    case HD_KF_LOCK_OUTPUT: return b->order * in->d_output_angle_rad;
    default: return HD_TWO_PI_F * b->order * ts_s;
    }
}

/* Per-step rotation of every active slot; decides which blocks are frozen. */
typedef struct {
    float c[HD_KF_MAX_BLOCKS];
    float s[HD_KF_MAX_BLOCKS];
    float q_scale[HD_KF_MAX_BLOCKS]; /* process-noise scale for this step */
    float gain[HD_KF_MAX_STATES];    /* gain fraction per state (1: optimal) */
    bool frozen[HD_KF_MAX_BLOCKS]; /* by slot */
} step_rotation_t;

/* min(1, |theta| / ref) for angle-locked blocks when enabled, else 1. */
/* The motion fraction min(1, |angle| / q_motion_ref_rad); 1 when off. */
static float motion_fraction(const v0_kf_t *kf, float angle_rad)
{
    const float ref = kf->cfg.q_motion_ref_rad;
    const float abs_angle = angle_rad < 0.0f ? -angle_rad : angle_rad;
    return (ref <= 0.0f || abs_angle >= ref) ? 1.0f : abs_angle / ref;
}

static float motion_q_scale(const v0_kf_t *kf, const hd_kf_block_config_t *b,
                            float theta)
{
    return b->lock == HD_KF_LOCK_FIXED ? 1.0f : motion_fraction(kf, theta);
}

static void compute_rotations(v0_kf_t *kf, const hd_kf_input_t *in,
                              step_rotation_t *rot)
{
    const float limit = kf->cfg.nyquist_fraction * HD_PI_F;
    uint32_t frozen_now = 0u;
    /* Slots past active_blocks are never read; defined anyway, so static
     * analysis can see every read of frozen[] is of a written entry. */
    for (unsigned s = 0; s < HD_KF_MAX_BLOCKS; s++) {
        rot->frozen[s] = true;
    }
    for (unsigned s = 0; s < kf->active_blocks; s++) {
        const unsigned b = kf->block_index[s];
        const float theta = block_theta(&kf->cfg.blocks[b], in, kf->cfg.ts_s);
        const bool frozen = !(theta <= limit && theta >= -limit);
        rot->frozen[s] = frozen;
        rot->q_scale[s] = motion_q_scale(kf, &kf->cfg.blocks[b], theta);
        /* Motor-locked blocks learn in proportion to their motion (hd_kf.h,
         * "Slow motor blocks"); output-locked ones always turn slowly and
         * rely on their small prior instead. */
        rot->gain[2u * s] = rot->gain[2u * s + 1u] =
            kf->cfg.blocks[b].lock == HD_KF_LOCK_MOTOR ? rot->q_scale[s] : 1.0f;
        if (frozen) {
            /* Held (hd_kf.h, "Nyquist"): not observed, not corrected, but
             * still turned by the measured increment, which is exact at any
             * speed, unless no motion can explain it. */
            frozen_now |= 1u << b;
            rot->gain[2u * s] = rot->gain[2u * s + 1u] = 0.0f;
            if (!(theta <= HD_KF_PHASE_LOST_RAD && theta >= -HD_KF_PHASE_LOST_RAD)) {
                reset_state_cov(kf, 2u * s, block_p0(kf, b));
                reset_state_cov(kf, 2u * s + 1u, block_p0(kf, b));
            }
        }
        hd_sincosf(theta, &rot->s[s], &rot->c[s]);
    }
    kf->frozen_mask = frozen_now;
    if (kf->cfg.offset_enabled) {
        rot->gain[kf->offset_slot] = 1.0f;
    }
}

/* [u; v] <- [c s; -s c] [u; v]: one block of Phi applied to a pair. */
static void rotate_pair(float *u, float *v, float c, float s)
{
    const float u0 = *u, v0 = *v;
    *u = c * u0 + s * v0;
    *v = c * v0 - s * u0;
}

/* Symmetric rank-1 downdate on the upper triangle, then the block rotation
 * P <- Phi P Phi', then Q; mirrors to keep P symmetric.  The downdate is the
 * Joseph form for the gain F g / S (F = diag(gain), hd_kf.h "Slow motor
 * blocks"): P_ij -= (f_i + f_j - f_i f_j) g_i g_j / S, which is g g' / S
 * when every f is 1 and keeps P the exact covariance of the suboptimal
 * estimate otherwise. */
static void covariance_update(v0_kf_t *kf, const float *g, float inv_s,
                              bool correct, const step_rotation_t *rot)
{
    const unsigned n = kf->n_states;
    float(*p)[HD_KF_MAX_STATES] = kf->p;
    if (correct) {
        for (unsigned i = 0; i < n; i++) {
            const float gi = g[i] * inv_s;
            for (unsigned j = i; j < n; j++) {
                const float w = rot->gain[i] + rot->gain[j] - rot->gain[i] * rot->gain[j];
                p[i][j] -= w * gi * g[j];
            }
        }
        for (unsigned i = 0; i < n; i++) {
            for (unsigned j = 0; j < i; j++) {
                p[i][j] = p[j][i];
            }
        }
    }
    /* P <- Phi P Phi': rotate the block's row pair, then its column pair. */
    for (unsigned s = 0; s < kf->active_blocks; s++) {
        const unsigned a = 2u * s, b = a + 1u;
        for (unsigned j = 0; j < n; j++) {
            rotate_pair(&p[a][j], &p[b][j], rot->c[s], rot->s[s]);
        }
        for (unsigned i = 0; i < n; i++) {
            rotate_pair(&p[i][a], &p[i][b], rot->c[s], rot->s[s]);
        }
    }
    /* Exact symmetry: the upper triangle is the reference. */
    for (unsigned i = 0; i < n; i++) {
        for (unsigned j = 0; j < i; j++) {
            p[i][j] = p[j][i];
        }
    }
    /* + Q (frozen blocks are held: no process noise) */
    for (unsigned s = 0; s < kf->active_blocks; s++) {
        if (!rot->frozen[s]) {
            const float q = kf->cfg.blocks[kf->block_index[s]].q_nm2 * rot->q_scale[s];
            p[2u * s][2u * s] += q;
            p[2u * s + 1u][2u * s + 1u] += q;
        }
    }
    if (kf->cfg.offset_enabled) {
        p[kf->offset_slot][kf->offset_slot] += kf->cfg.offset_q_nm2;
    }
}

/* Keeps every diagonal in [0, p_max] with congruence scalings (PSD kept);
 * returns true if anything was clamped. */
static bool clamp_covariance(v0_kf_t *kf)
{
    const unsigned n = kf->n_states;
    const float p_max = kf->cfg.p_max_nm2;
    bool clamped = false;
    for (unsigned i = 0; i < n; i++) {
        const float d = kf->p[i][i];
        if (d < 0.0f) {
            /* Rounding pushed a variance below zero: drop the state's
             * correlations; zero variance is the closest PSD choice. */
            for (unsigned j = 0; j < n; j++) {
                kf->p[i][j] = 0.0f;
                kf->p[j][i] = 0.0f;
            }
            clamped = true;
        } else if (d > p_max) {
            const float scale = sqrtf(p_max / d);
            for (unsigned j = 0; j < n; j++) {
                kf->p[i][j] *= scale;
                kf->p[j][i] *= scale;
            }
            kf->p[i][i] = p_max;
            clamped = true;
        }
    }
    return clamped;
}

static bool state_is_finite(const v0_kf_t *kf)
{
    for (unsigned i = 0; i < kf->n_states; i++) {
        /* Off-diagonals are bounded by the diagonals while P is PSD; a
         * non-finite entry anywhere shows up in x, the diagonal or g. */
        if (!is_finite(kf->x[i]) || !is_finite(kf->p[i][i])) {
            return false;
        }
    }
    return true;
}

/* Measurement-row scale of motor-locked blocks: 1 + k |T_ref| (hd_kf.h,
 * "Load-dependent ripple"); 1 when off.  T_ref follows T_exp + offset by
 * the motor's motion fraction and is held at standstill.  |T_ref| is
 * clamped to HD_KF_MAX_ABS_Y_NM and k to HD_KF_MAX_LOAD_COEFF_PER_NM, so c
 * stays finite. */
static float update_load_scale(v0_kf_t *kf, const hd_kf_input_t *in)
{
    const float k = kf->cfg.ripple_load_coeff_per_nm;
    if (k <= 0.0f) {
        return 1.0f;
    }
    float t_now = is_finite(in->torque_expected_nm) ? in->torque_expected_nm : 0.0f;
    if (kf->cfg.offset_enabled && !kf->cfg.offset_is_sensor_error && kf->offset_primed) {
        t_now += kf->x[kf->offset_slot];
    }
    if (!kf->load_ref_primed) {
        kf->load_ref_nm = t_now;
        kf->load_ref_primed = 1u;
    } else {
        kf->load_ref_nm += motion_fraction(kf, in->d_motor_angle_rad) * (t_now - kf->load_ref_nm);
    }
    const float t = kf->load_ref_nm < 0.0f ? -kf->load_ref_nm : kf->load_ref_nm;
    return 1.0f + k * (t < HD_KF_MAX_ABS_Y_NM ? t : HD_KF_MAX_ABS_Y_NM);
}

/* C entry of an unfrozen slot: the load scale for motor-locked blocks
 * (meshing ripple), 1 for output-locked (misalignment is geometry) and
 * fixed-frequency ones (electrical pickup). */
static float block_c(const v0_kf_t *kf, unsigned slot, float c_load)
{
    return kf->cfg.blocks[kf->block_index[slot]].lock == HD_KF_LOCK_MOTOR ? c_load : 1.0f;
}

void v0_kf_step(v0_kf_t *kf, const hd_kf_input_t *in_raw, v0_kf_output_t *out)
{
    uint32_t status = 0u;
    hd_kf_input_t in = *in_raw;
    if (!is_finite(in.d_motor_angle_rad)) {
        in.d_motor_angle_rad = 0.0f;
        status |= HD_KF_STATUS_BAD_INPUT;
    }
    if (!is_finite(in.d_output_angle_rad)) {
        in.d_output_angle_rad = 0.0f;
        status |= HD_KF_STATUS_BAD_INPUT;
    }
    const float y = in.torque_meas_nm - in.torque_expected_nm;
    /* A finite but absurd y (a broken sensor, a bad log) would square to
     * infinity in the update and reset the whole filter: treat it as bad
     * input instead, like a non-finite one. */
    const bool correct = y <= HD_KF_MAX_ABS_Y_NM && y >= -HD_KF_MAX_ABS_Y_NM;
    if (!correct) {
        status |= HD_KF_STATUS_BAD_INPUT;
    }

    step_rotation_t rot;
    compute_rotations(kf, &in, &rot);
    const unsigned n = kf->n_states;
    const float c_load = update_load_scale(kf, &in);

    /* The measurement row C for this step: the load scale (or 1) on each
     * unfrozen block's first state, 1 on the offset, 0 elsewhere. */
    float c_row[HD_KF_MAX_STATES];
    for (unsigned i = 0; i < n; i++) {
        c_row[i] = 0.0f;
    }
    for (unsigned s = 0; s < kf->active_blocks; s++) {
        c_row[2u * s] = rot.frozen[s] ? 0.0f : block_c(kf, s, c_load);
    }
    /* Prior outputs: ripple = C x without the offset. */
    float ripple = 0.0f;
    for (unsigned i = 0; i < n; i++) {
        ripple += c_row[i] * kf->x[i];
    }
    if (kf->cfg.offset_enabled) {
        c_row[kf->offset_slot] = 1.0f;
        if (!kf->offset_primed && correct) {
            kf->x[kf->offset_slot] = y - ripple;
            kf->offset_primed = 1u;
        }
    }
    const float offset = kf->cfg.offset_enabled ? kf->x[kf->offset_slot] : 0.0f;

    /* g = P C' and S = R + C P C'; C is nonzero only on block first states
     * and the offset, so g sums over those columns. */
    float g[HD_KF_MAX_STATES];
    float cpc = 0.0f;
    for (unsigned i = 0; i < n; i++) {
        float sum = 0.0f;
        for (unsigned s = 0; s < kf->active_blocks; s++) {
            sum += kf->p[i][2u * s] * c_row[2u * s];
        }
        if (kf->cfg.offset_enabled) {
            sum += kf->p[i][kf->offset_slot];
        }
        g[i] = sum;
        cpc += c_row[i] * sum;
    }
    float s_var = kf->cfg.r_nm2 + cpc;
    const float innovation = y - ripple - offset;
    const float jump_nm = kf->cfg.offset_jump_nm;
    const float e2 = innovation * innovation;
    if (correct && kf->cfg.offset_enabled && jump_nm > 0.0f &&
        e2 > jump_nm * jump_nm && e2 > JUMP_MIN_SIGMA * JUMP_MIN_SIGMA * s_var) {
        status |= HD_KF_STATUS_OFFSET_JUMP;
        kf->p[kf->offset_slot][kf->offset_slot] += e2;
        g[kf->offset_slot] += e2;
        s_var += e2;
    }
    const float inv_s = 1.0f / s_var;

    out->ripple_nm = ripple;
    out->offset_nm = offset;
    out->innovation_nm = correct ? innovation : 0.0f;
    out->innovation_var_nm2 = s_var;
    out->torque_filtered_nm = in.torque_meas_nm - ripple -
                              (kf->cfg.offset_is_sensor_error ? offset : 0.0f);
    for (unsigned b = 0; b < HD_KF_MAX_BLOCKS; b++) {
        out->amplitude_nm[b] = 0.0f;
    }
    for (unsigned s = 0; s < kf->active_blocks; s++) {
        if (!rot.frozen[s]) {
            const float a = kf->x[2u * s], b = kf->x[2u * s + 1u];
            out->amplitude_nm[kf->block_index[s]] = c_row[2u * s] * sqrtf(a * a + b * b);
        }
    }

    /* State: x <- Phi (x + g e / S)   (equation 8) */
    if (correct) {
        const float k = innovation * inv_s;
        for (unsigned i = 0; i < n; i++) {
            kf->x[i] += rot.gain[i] * g[i] * k;
        }
    }
    for (unsigned s = 0; s < kf->active_blocks; s++) {
        rotate_pair(&kf->x[2u * s], &kf->x[2u * s + 1u], rot.c[s], rot.s[s]);
    }
    /* Covariance: equations 9-10 in the same factored form */
    covariance_update(kf, g, inv_s, correct, &rot);
    if (clamp_covariance(kf)) {
        status |= HD_KF_STATUS_P_CLAMPED;
    }
    if (!state_is_finite(kf) || !is_finite(s_var)) {
        v0_kf_reset(kf);
        kf->reset_count++;
        status |= HD_KF_STATUS_RESET;
    }
    if (kf->frozen_mask != 0u) {
        status |= HD_KF_STATUS_FROZEN;
    }
    if (status & HD_KF_STATUS_BAD_INPUT) {
        kf->bad_input_count++;
    }
    out->frozen_mask = kf->frozen_mask;
    out->status = status;
    kf->status_sticky |= status;
    if (!is_finite(out->torque_filtered_nm)) {
        /* Never publish a non-finite estimate: fall back to the measurement
         * (or 0 if that is not finite either). */
        out->torque_filtered_nm = is_finite(in.torque_meas_nm) ? in.torque_meas_nm : 0.0f;
        out->ripple_nm = 0.0f;
    }
}


void v0_kf_init(v0_kf_t *kf, const hd_kf_config_t *cfg)
{
    kf->cfg = *cfg;
    build_layout(kf);
    v0_kf_reset(kf);
    kf->status_sticky = 0u;
    kf->reset_count = 0u;
    kf->bad_input_count = 0u;
}
