/* hd_kf: see hd_kf.h for the model, the update and the invariants. */
#include "hd_kf.h"

#include <math.h> /* sqrtf (VSQRT on Cortex-M4F), atan2f (outside the 1 kHz path) */
#include <stddef.h>

#include "hd_trig.h"

#define DEFAULT_R_NM2 1.0f
/* A prior on ripple amplitude (~0.5 N m per state), not 'unknown': with
 * R = 4e-4 N m^2 a p0 of 10 puts a 2.5e4 spread into P, and float32 then
 * loses the split between collinear states at standstill (measured against
 * the double reference: 0.1 N m; with 0.3 N m^2: 3e-3 N m). */
#define DEFAULT_P0_NM2 0.3f
#define DEFAULT_P_MAX_NM2 1.0e6f
#define DEFAULT_NYQUIST_FRACTION 0.9f
#define DEFAULT_OFFSET_Q_NM2 1.0e-6f
#define RECOMMENDED_Q_MOTION_REF_RAD 0.05f
#define RECOMMENDED_OUTPUT_P0_NM2 0.01f
#define PAPER_Q_NM2 1.0e3f
#define PAPER_R_NM2 1.0f
#define RECOMMENDED_JUMP_NOISE_MULTIPLE 25.0f
#define JUMP_MIN_SIGMA 4.0f

/* isfinite without libm calls; x - x is 0 only for finite x. */
static bool is_finite(float x)
{
    return (x - x) == 0.0f;
}

void hd_kf_config_default(hd_kf_config_t *cfg, float ts_s)
{
    *cfg = (hd_kf_config_t){0};
    cfg->r_nm2 = DEFAULT_R_NM2;
    cfg->ts_s = ts_s;
    cfg->p0_nm2 = DEFAULT_P0_NM2;
    cfg->p_max_nm2 = DEFAULT_P_MAX_NM2;
    cfg->nyquist_fraction = DEFAULT_NYQUIST_FRACTION;
    cfg->offset_q_nm2 = DEFAULT_OFFSET_Q_NM2;
    cfg->output_p0_nm2 = DEFAULT_P0_NM2;
}

void hd_kf_config_paper(hd_kf_config_t *cfg, float ts_s, bool with_misalignment)
{
    hd_kf_config_default(cfg, ts_s);
    cfg->r_nm2 = PAPER_R_NM2;
    cfg->p0_nm2 = PAPER_Q_NM2;
    cfg->output_p0_nm2 = PAPER_Q_NM2;
    (void)hd_kf_config_add_block(cfg, HD_KF_LOCK_MOTOR, 2.0f, PAPER_Q_NM2);
    (void)hd_kf_config_add_block(cfg, HD_KF_LOCK_MOTOR, 4.0f, PAPER_Q_NM2);
    if (with_misalignment) {
        (void)hd_kf_config_add_block(cfg, HD_KF_LOCK_OUTPUT, 1.0f, PAPER_Q_NM2);
    }
}

void hd_kf_config_recommended(hd_kf_config_t *cfg, float ts_s, float noise_nm,
                              float ripple_settle_s, float offset_settle_s)
{
    hd_kf_config_default(cfg, ts_s);
    /* R: white sensor noise.  For a scalar random-walk observed in noise the
     * steady-state gain is ~sqrt(q/r), i.e. a time constant ~ ts/sqrt(q/r);
     * choose q so each state settles in the requested time. */
    const float r = noise_nm * noise_nm;
    const float ripple_ratio = ts_s / ripple_settle_s;
    const float offset_ratio = ts_s / offset_settle_s;
    const float q_ripple = r * ripple_ratio * ripple_ratio;
    cfg->r_nm2 = r;
    cfg->offset_enabled = 1u;
    cfg->offset_q_nm2 = r * offset_ratio * offset_ratio;
    cfg->offset_jump_nm = RECOMMENDED_JUMP_NOISE_MULTIPLE * noise_nm;
    cfg->q_motion_ref_rad = RECOMMENDED_Q_MOTION_REF_RAD;
    cfg->output_p0_nm2 = RECOMMENDED_OUTPUT_P0_NM2;
    /* A very quiet sensor: keep p0 / R inside the float32 bound. */
    const float p0_limit = 0.5f * HD_KF_MAX_P0_OVER_R * r;
    if (cfg->p0_nm2 > p0_limit) {
        cfg->p0_nm2 = p0_limit;
    }
    if (cfg->output_p0_nm2 > p0_limit) {
        cfg->output_p0_nm2 = p0_limit;
    }
    (void)hd_kf_config_add_block(cfg, HD_KF_LOCK_MOTOR, 2.0f, q_ripple);
    (void)hd_kf_config_add_block(cfg, HD_KF_LOCK_MOTOR, 4.0f, q_ripple);
    (void)hd_kf_config_add_block(cfg, HD_KF_LOCK_OUTPUT, 1.0f, q_ripple);
}

int hd_kf_config_add_block(hd_kf_config_t *cfg, hd_kf_lock_t lock, float order,
                           float q_nm2)
{
    if (cfg == NULL) {
        return HD_KF_ERR_NULL;
    }
    if (cfg->block_count >= HD_KF_MAX_BLOCKS) {
        return HD_KF_ERR_BLOCK_COUNT;
    }
    hd_kf_block_config_t *b = &cfg->blocks[cfg->block_count];
    b->lock = (uint8_t)lock;
    b->enabled = 1u;
    b->order = order;
    b->q_nm2 = q_nm2;
    return cfg->block_count++;
}

static bool is_nonneg(float x)
{
    return is_finite(x) && x >= 0.0f;
}

static hd_kf_err_t check_block(const hd_kf_block_config_t *b, float ts_s)
{
    if (b->lock > HD_KF_LOCK_FIXED) {
        return HD_KF_ERR_LOCK;
    }
    if (!is_finite(b->order) || b->order <= 0.0f) {
        return HD_KF_ERR_ORDER;
    }
    if (!is_nonneg(b->q_nm2)) {
        return HD_KF_ERR_NOISE;
    }
    if (b->lock == HD_KF_LOCK_FIXED && b->order * ts_s >= 0.5f) {
        return HD_KF_ERR_FIXED_OVER_NYQUIST;
    }
    return HD_KF_OK;
}

hd_kf_err_t hd_kf_config_check(const hd_kf_config_t *cfg)
{
    if (cfg == NULL) {
        return HD_KF_ERR_NULL;
    }
    if (cfg->block_count > HD_KF_MAX_BLOCKS) {
        return HD_KF_ERR_BLOCK_COUNT;
    }
    if (!is_finite(cfg->ts_s) || cfg->ts_s <= 0.0f) {
        return HD_KF_ERR_TS;
    }
    if (!is_finite(cfg->r_nm2) || cfg->r_nm2 <= 0.0f || !is_nonneg(cfg->p0_nm2) ||
        !is_finite(cfg->p_max_nm2) || cfg->p_max_nm2 <= 0.0f ||
        cfg->p0_nm2 > cfg->p_max_nm2 ||
        (cfg->offset_enabled && !is_nonneg(cfg->offset_q_nm2))) {
        return HD_KF_ERR_NOISE;
    }
    if (!is_nonneg(cfg->offset_jump_nm) || !is_nonneg(cfg->q_motion_ref_rad) ||
        !is_nonneg(cfg->ripple_load_coeff_per_nm) ||
        cfg->ripple_load_coeff_per_nm > HD_KF_MAX_LOAD_COEFF_PER_NM ||
        !is_nonneg(cfg->output_p0_nm2) || cfg->output_p0_nm2 > cfg->p_max_nm2) {
        return HD_KF_ERR_NOISE;
    }
    if (cfg->p0_nm2 > HD_KF_MAX_P0_OVER_R * cfg->r_nm2 ||
        cfg->output_p0_nm2 > HD_KF_MAX_P0_OVER_R * cfg->r_nm2) {
        return HD_KF_ERR_CONDITION;
    }
    if (!is_finite(cfg->nyquist_fraction) || cfg->nyquist_fraction <= 0.0f ||
        cfg->nyquist_fraction > 1.0f) {
        return HD_KF_ERR_NYQUIST;
    }
    for (unsigned i = 0; i < cfg->block_count; i++) {
        const hd_kf_err_t err = check_block(&cfg->blocks[i], cfg->ts_s);
        if (err != HD_KF_OK) {
            return err;
        }
    }
    return HD_KF_OK;
}

const char *hd_kf_err_str(int err)
{
    switch (err) {
    case HD_KF_OK: return "ok";
    case HD_KF_ERR_NULL: return "null pointer";
    case HD_KF_ERR_BLOCK_COUNT: return "too many blocks (HD_KF_MAX_BLOCKS)";
    case HD_KF_ERR_LOCK: return "unknown block lock kind";
    case HD_KF_ERR_ORDER: return "block order/frequency must be finite and > 0";
    case HD_KF_ERR_NOISE: return "q, r, p0, p_max, gates and load coefficient must be finite, q >= 0, r > 0, p0 <= p_max, load coefficient <= HD_KF_MAX_LOAD_COEFF_PER_NM";
    case HD_KF_ERR_TS: return "sample period must be finite and > 0";
    case HD_KF_ERR_NYQUIST: return "nyquist_fraction must be in (0, 1]";
    case HD_KF_ERR_FIXED_OVER_NYQUIST: return "fixed-frequency block at or above fs/2";
    case HD_KF_ERR_CONDITION: return "p0 / r above HD_KF_MAX_P0_OVER_R: float32 would lose the covariance";
    default: return "unknown error";
    }
}

static float block_p0(const hd_kf_t *kf, unsigned block)
{
    return kf->cfg.blocks[block].lock == HD_KF_LOCK_OUTPUT ? kf->cfg.output_p0_nm2
                                                          : kf->cfg.p0_nm2;
}

/* Zeroes row and column i of P and sets the diagonal to p0: the state
 * restarts with no correlation to the others (keeps P PSD). */
static void reset_state_cov(hd_kf_t *kf, unsigned i, float p0_nm2)
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
static void build_layout(hd_kf_t *kf)
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

void hd_kf_reset(hd_kf_t *kf)
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

hd_kf_err_t hd_kf_init(hd_kf_t *kf, const hd_kf_config_t *cfg)
{
    if (kf == NULL) {
        return HD_KF_ERR_NULL;
    }
    const hd_kf_err_t err = hd_kf_config_check(cfg);
    if (err != HD_KF_OK) {
        return err;
    }
    kf->cfg = *cfg;
    build_layout(kf);
    hd_kf_reset(kf);
    kf->status_sticky = 0u;
    kf->reset_count = 0u;
    kf->bad_input_count = 0u;
    return HD_KF_OK;
}

/* New state i takes old state src[i] (-1: a new state, zero with its p0).
 * In place, no copy of P: src is monotone, so for a compaction (src[i] >= i)
 * an ascending sweep never reads an entry it already overwrote, and for an
 * expansion (src[i] <= i) a descending sweep does not either. */
static void remap_states(hd_kf_t *kf, const int *src, unsigned n_new, bool ascending)
{
    for (unsigned step = 0; step < n_new; step++) {
        const unsigned i = ascending ? step : n_new - 1u - step;
        for (unsigned step_j = 0; step_j < n_new; step_j++) {
            const unsigned j = ascending ? step_j : n_new - 1u - step_j;
            kf->p[i][j] = (src[i] < 0 || src[j] < 0) ? 0.0f : kf->p[src[i]][src[j]];
        }
        kf->x[i] = src[i] < 0 ? 0.0f : kf->x[src[i]];
    }
    for (unsigned i = 0; i < HD_KF_MAX_STATES; i++) {
        for (unsigned j = 0; j < HD_KF_MAX_STATES; j++) {
            if (i >= n_new || j >= n_new) {
                kf->p[i][j] = 0.0f;
            }
        }
        if (i >= n_new) {
            kf->x[i] = 0.0f;
        }
    }
}

hd_kf_err_t hd_kf_set_block_enabled(hd_kf_t *kf, unsigned block, bool enabled)
{
    if (kf == NULL) {
        return HD_KF_ERR_NULL;
    }
    if (block >= kf->cfg.block_count) {
        return HD_KF_ERR_BLOCK_COUNT;
    }
    if ((kf->cfg.blocks[block].enabled != 0u) == enabled) {
        return HD_KF_OK;
    }
    /* Old slot of every configured block, then the new compact layout. */
    int old_slot_of[HD_KF_MAX_BLOCKS];
    for (unsigned i = 0; i < HD_KF_MAX_BLOCKS; i++) {
        old_slot_of[i] = -1;
    }
    for (unsigned s = 0; s < kf->active_blocks; s++) {
        old_slot_of[kf->block_index[s]] = (int)s;
    }
    const unsigned old_offset = kf->offset_slot;
    kf->cfg.blocks[block].enabled = enabled ? 1u : 0u;
    build_layout(kf);

    int src[HD_KF_MAX_STATES];
    for (unsigned s = 0; s < kf->active_blocks; s++) {
        const int old = old_slot_of[kf->block_index[s]];
        src[2u * s] = old < 0 ? -1 : 2 * old;
        src[2u * s + 1u] = old < 0 ? -1 : 2 * old + 1;
    }
    if (kf->cfg.offset_enabled) {
        src[kf->offset_slot] = (int)old_offset;
    }
    remap_states(kf, src, kf->n_states, !enabled);
    if (enabled) {
        /* the re-enabled block restarts from zero with its initial variance */
        for (unsigned i = 0; i < kf->n_states; i++) {
            if (src[i] < 0) {
                kf->p[i][i] = block_p0(kf, block);
            }
        }
    }
    kf->frozen_mask &= ~(1u << block);
    return HD_KF_OK;
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
static float motion_fraction(const hd_kf_t *kf, float angle_rad)
{
    const float ref = kf->cfg.q_motion_ref_rad;
    const float abs_angle = angle_rad < 0.0f ? -angle_rad : angle_rad;
    return (ref <= 0.0f || abs_angle >= ref) ? 1.0f : abs_angle / ref;
}

static float motion_q_scale(const hd_kf_t *kf, const hd_kf_block_config_t *b,
                            float theta)
{
    return b->lock == HD_KF_LOCK_FIXED ? 1.0f : motion_fraction(kf, theta);
}

static void compute_rotations(hd_kf_t *kf, const hd_kf_input_t *in,
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
static void covariance_update(hd_kf_t *kf, const float *g, float inv_s,
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
static bool clamp_covariance(hd_kf_t *kf)
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

static bool state_is_finite(const hd_kf_t *kf)
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
static float update_load_scale(hd_kf_t *kf, const hd_kf_input_t *in)
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
static float block_c(const hd_kf_t *kf, unsigned slot, float c_load)
{
    return kf->cfg.blocks[kf->block_index[slot]].lock == HD_KF_LOCK_MOTOR ? c_load : 1.0f;
}

void hd_kf_step(hd_kf_t *kf, const hd_kf_input_t *in_raw, hd_kf_output_t *out)
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
        hd_kf_reset(kf);
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

void hd_kf_block_amplitude_phase(const hd_kf_t *kf, unsigned block,
                                 float *amplitude_nm, float *phase_rad)
{
    *amplitude_nm = 0.0f;
    *phase_rad = 0.0f;
    for (unsigned s = 0; s < kf->active_blocks; s++) {
        if (kf->block_index[s] == block && (kf->frozen_mask & (1u << block)) == 0u) {
            const float a = kf->x[2u * s], b = kf->x[2u * s + 1u];
            *amplitude_nm = sqrtf(a * a + b * b);
            /* ripple = A cos(phase): x1 = A cos(phase), x2 = -A sin(phase) */
            *phase_rad = atan2f(-b, a);
        }
    }
}

unsigned hd_kf_state_count(const hd_kf_t *kf)
{
    return kf->n_states;
}

float hd_kf_state(const hd_kf_t *kf, unsigned i)
{
    return i < kf->n_states ? kf->x[i] : 0.0f;
}

float hd_kf_cov(const hd_kf_t *kf, unsigned i, unsigned j)
{
    return (i < kf->n_states && j < kf->n_states) ? kf->p[i][j] : 0.0f;
}
