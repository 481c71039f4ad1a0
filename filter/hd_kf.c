/* hd_kf: see hd_kf.h for the contracts, docs/design/filter.md for the design. */
#include "hd_kf.h"

#include <math.h> /* sqrtf (VSQRT on Cortex-M4F): clamp and read-out; atan2f: read-out only */
#include <stddef.h>

#include "hd_kf_internal.h"
#include "hd_trig.h"

#define DEFAULT_R_NM2 1.0f
#define DEFAULT_P0_NM2 0.3f /* an amplitude prior (docs/design/filter.md, "Priors") */
#define DEFAULT_P_MAX_NM2 1.0e6f
#define DEFAULT_NYQUIST_FRACTION 0.9f
#define DEFAULT_OFFSET_Q_NM2 1.0e-6f
#define DEFAULT_OUTPUT_LEARN_SCALE 1.0f
#define RECOMMENDED_Q_MOTION_REF_RAD 0.05f
#define RECOMMENDED_OUTPUT_P0_NM2 0.01f
#define PAPER_Q_NM2 1.0e3f
#define PAPER_R_NM2 1.0f
#define RECOMMENDED_JUMP_NOISE_MULTIPLE 25.0f
/* Layouts of MIN_LAYOUT_BLOCKS to UNROLLED_BLOCKS blocks have their own
 * instance; smaller models take the smallest, larger ones HD_KF_MAX_BLOCKS
 * slots, the unused slots held at zero like a disabled block. */
#define MIN_LAYOUT_BLOCKS (HD_KF_MAX_BLOCKS < 2 ? HD_KF_MAX_BLOCKS : 2u)
#define UNROLLED_BLOCKS 4u

/* ===================================================================== */
/* Configuration                                                          */
/* ===================================================================== */

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
    cfg->output_learn_scale = DEFAULT_OUTPUT_LEARN_SCALE;
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
    /* For a random walk observed in noise the steady gain is ~sqrt(q/r):
     * q = r (ts / settle)^2 settles in ~settle. */
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
        !is_nonneg(cfg->q_motion_ref_profiled_rad) ||
        !is_nonneg(cfg->ripple_load_coeff_per_nm) ||
        cfg->ripple_load_coeff_per_nm > HD_KF_MAX_LOAD_COEFF_PER_NM ||
        !is_nonneg(cfg->output_p0_nm2) || cfg->output_p0_nm2 > cfg->p_max_nm2 ||
        !is_nonneg(cfg->offset_drift_q_nm2) || cfg->offset_drift_q_nm2 > cfg->p_max_nm2) {
        return HD_KF_ERR_NOISE;
    }
    if (!is_nonneg(cfg->output_row_follow) || cfg->output_row_follow > 1.0f ||
        (cfg->output_row_follow > 0.0f &&
         (!(cfg->output_row_max >= 1.0f) || cfg->output_row_max > HD_KF_MAX_OUTPUT_ROW))) {
        return HD_KF_ERR_LEARN_SCALE;
    }
    if (cfg->p0_nm2 > HD_KF_MAX_P0_OVER_R * cfg->r_nm2 ||
        cfg->output_p0_nm2 > HD_KF_MAX_P0_OVER_R * cfg->r_nm2) {
        return HD_KF_ERR_CONDITION;
    }
    if (!is_finite(cfg->nyquist_fraction) || cfg->nyquist_fraction <= 0.0f ||
        cfg->nyquist_fraction > 1.0f) {
        return HD_KF_ERR_NYQUIST;
    }
    if (!is_nonneg(cfg->output_learn_scale) || cfg->output_learn_scale > 1.0f) {
        return HD_KF_ERR_LEARN_SCALE;
    }
    if (!is_nonneg(cfg->correction_max_nm) || cfg->correction_max_nm > HD_KF_MAX_ABS_Y_NM) {
        return HD_KF_ERR_CORRECTION_MAX;
    }
    for (unsigned i = 0; i < cfg->block_count; i++) {
        const hd_kf_err_t err = check_block(&cfg->blocks[i], cfg->ts_s);
        if (err != HD_KF_OK) {
            return err;
        }
    }
    return HD_KF_OK;
}

const char *hd_kf_status_name(unsigned bit)
{
    static const char *const NAMES[HD_KF_STATUS_BITS] = {
        "FROZEN", "BAD_INPUT", "RESET", "P_CLAMPED", "OFFSET_JUMP", "LIMITED", "UNMODELLED",
        "LOAD_BOUND"};
    return bit < HD_KF_STATUS_BITS ? NAMES[bit] : NULL;
}

/* ===================================================================== */
/* Layout: slots, frames and the packed covariance                        */
/* ===================================================================== */

/* Marks the powers z^k that computing z^order by doubling (even k) and one
 * product (odd k) passes through. */
static void need_power(uint32_t *mask, unsigned k)
{
    while (k >= 1u && (*mask & (1u << k)) == 0u) {
        *mask |= 1u << k;
        if (k > 1u) {
            *mask |= 1u << 1u;
        }
        k = (k % 2u == 0u) ? k / 2u : k - 1u;
    }
}

/* The first non-negative float d (by bit pattern, which orders them) for
 * which pred(kf, sl, d) holds, pred being monotone: false below it, true
 * from it on (0x7f800000, +inf, if never). */
static float first_float(const hd_kf_t *kf, const hd_kf_slot_t *sl,
                         bool (*pred)(const hd_kf_t *, const hd_kf_slot_t *, float))
{
    uint32_t lo = 0u, hi = FLOAT_INF_BITS; /* pred(hi) taken as true */
    while (lo < hi) {
        const uint32_t mid = lo + (hi - lo) / 2u;
        const float_bits_t b = {.u = mid};
        if (pred(kf, sl, b.f)) {
            hi = mid;
        } else {
            lo = mid + 1u;
        }
    }
    const float_bits_t b = {.u = lo};
    return b.f;
}

/* plan_block's motion fraction reaches 1 (with its arithmetic). */
static bool motion_full(const hd_kf_t *kf, const hd_kf_slot_t *sl, float d)
{
    (void)kf;
    return fabsf(sl->theta_per_unit * d) * sl->motion_inv + sl->motion_bias >= 1.0f;
}

/* plan_block's Nyquist test fails (with its arithmetic). */
static bool over_nyquist(const hd_kf_t *kf, const hd_kf_slot_t *sl, float d)
{
    return !(fabsf(sl->theta_per_unit * d) <= kf->nyquist_limit_rad);
}

/* Slot s's motion fraction from the reference ref_rad (0: none, motion 1;
 * fixed blocks never scaled) and its full-motion increment full_rad. */
static void set_motion_ref(hd_kf_t *kf, unsigned s, float ref_rad, float full_rad)
{
    hd_kf_slot_t *sl = &kf->slot[s];
    const bool motion_scaled = ref_rad > 0.0f && sl->lock != HD_KF_LOCK_FIXED;
    sl->motion_inv = motion_scaled ? 1.0f / ref_rad : 0.0f;
    sl->motion_bias = motion_scaled ? 0.0f : 1.0f;
    sl->full_rad = full_rad;
}

/* For a motor block, the increment from which its motion fraction is 1 at
 * the reference ref_rad (set on the slot, which keeps it); 0 otherwise. */
static float full_at(hd_kf_t *kf, unsigned s, float ref_rad)
{
    set_motion_ref(kf, s, ref_rad, 0.0f);
    const hd_kf_slot_t *sl = &kf->slot[s];
    return sl->lock == HD_KF_LOCK_MOTOR ? first_float(kf, sl, motion_full) : 0.0f;
}

static void build_slot(hd_kf_t *kf, unsigned block)
{
    const hd_kf_block_config_t *b = &kf->cfg.blocks[block];
    hd_kf_slot_t *sl = &kf->slot[block];
    *sl = (hd_kf_slot_t){0};
    sl->lock = b->lock;
    sl->enabled = b->enabled ? 1u : 0u;
    sl->theta_per_unit = b->order;
    sl->q_nm2 = b->q_nm2;
    sl->p0_nm2 = kf->cfg.p0_nm2;
    sl->learn = 1.0f;
    if (b->lock == HD_KF_LOCK_OUTPUT) {
        sl->p0_nm2 = kf->cfg.output_p0_nm2;
        sl->learn = kf->cfg.output_learn_scale;
        sl->q_nm2 = b->q_nm2 * kf->cfg.output_learn_scale;
    }
    if (b->lock == HD_KF_LOCK_FIXED) {
        sl->theta_per_unit = HD_TWO_PI_F * b->order * kf->cfg.ts_s;
        hd_sincosf(sl->theta_per_unit, &sl->fixed_sin, &sl->fixed_cos);
    }
    sl->full_profiled_rad = kf->cfg.q_motion_ref_profiled_rad > 0.0f
                                ? full_at(kf, block, kf->cfg.q_motion_ref_profiled_rad)
                                : 0.0f;
    sl->full_shared_rad = full_at(kf, block, kf->cfg.q_motion_ref_rad);
    sl->full_rad = sl->full_shared_rad;
    if (b->lock != HD_KF_LOCK_FIXED) {
        sl->frozen_rad = first_float(kf, sl, over_nyquist);
    }
    if (b->lock != HD_KF_LOCK_FIXED && b->order <= (float)MAX_POWER_ORDER &&
        b->order == (float)(unsigned)b->order) {
        const unsigned k = (unsigned)b->order;
        const bool motor = b->lock == HD_KF_LOCK_MOTOR;
        need_power(motor ? &kf->motor_powers : &kf->output_powers, k);
        sl->frame = (uint8_t)(motor ? k : POWER_TABLE_OUTPUT + k);
    } else {
        sl->frame = (uint8_t)(OWN_PHASORS + block);
        kf->own_frames |= 1u << block;
    }
}

/* The short plans' ranges and slots (intersections over the enabled
 * blocks' own thresholds, O(n): run-time toggles): every enabled motor
 * block is at motion fraction 1 and none is over Nyquist for |motor
 * increment| in [motor_full_rad, motor_frozen_rad); no enabled output block
 * is over Nyquist for |output increment| < output_frozen_rad.  Empty ranges
 * when there is no such block. */
static void short_plan_ranges(hd_kf_t *kf)
{
    kf->motor_full_rad = kf->motor_frozen_rad = kf->output_frozen_rad = 0.0f;
    kf->follow_min_rad = 0.0f;
    kf->motor_slots = kf->output_slots = kf->output_partial_slots = 0u;
    for (unsigned s = 0; s < kf->n_blocks; s++) {
        const hd_kf_slot_t *sl = &kf->slot[s];
        if (!sl->enabled) {
            continue;
        }
        if (sl->lock == HD_KF_LOCK_MOTOR) {
            const bool first = kf->motor_slots == 0u;
            if (first || sl->full_rad > kf->motor_full_rad) {
                kf->motor_full_rad = sl->full_rad;
            }
            if (first || sl->frozen_rad < kf->motor_frozen_rad) {
                kf->motor_frozen_rad = sl->frozen_rad;
            }
            kf->motor_slots |= 1u << s;
            const float min_rad = HD_KF_FOLLOW_MIN_RAD / sl->theta_per_unit;
            if (first || min_rad > kf->follow_min_rad) {
                kf->follow_min_rad = min_rad;
            }
        } else if (sl->lock == HD_KF_LOCK_OUTPUT) {
            if (kf->output_slots == 0u || sl->frozen_rad < kf->output_frozen_rad) {
                kf->output_frozen_rad = sl->frozen_rad;
            }
            kf->output_slots |= 1u << s;
            if (sl->learn < 1.0f) {
                kf->output_partial_slots |= 1u << s;
            }
        }
    }
}

void hd_kf_profile_motion(hd_kf_t *kf, uint32_t held)
{
    if (!(kf->cfg.q_motion_ref_profiled_rad > 0.0f)) {
        return; /* off: every block keeps q_motion_ref_rad (build_slot's) */
    }
    held &= (1u << kf->cfg.block_count) - 1u;
    const uint32_t changed = held ^ kf->profiled_slots;
    if (changed == 0u) {
        return; /* a reset with no line held: nothing to switch back (the tick's case) */
    }
    for (unsigned s = 0; s < kf->cfg.block_count; s++) {
        if ((changed & (1u << s)) == 0u) {
            continue;
        }
        const hd_kf_slot_t *sl = &kf->slot[s];
        if ((held & (1u << s)) != 0u) {
            set_motion_ref(kf, s, kf->cfg.q_motion_ref_profiled_rad, sl->full_profiled_rad);
        } else {
            set_motion_ref(kf, s, kf->cfg.q_motion_ref_rad, sl->full_shared_rad);
        }
    }
    kf->profiled_slots = held;
    short_plan_ranges(kf);
}

/* Builds every configured block's slot and the per-step constants.  A
 * model of more than UNROLLED_BLOCKS blocks gets HD_KF_MAX_BLOCKS slots,
 * the unused ones disabled. */
/* A duration in steps, at least 1 (ts_s > 0 and finite: hd_kf_config_check). */
static uint32_t steps_of(float duration_s, float ts_s)
{
    const float steps = duration_s / ts_s + 0.5f;
    return steps >= 1.0f ? (steps < 1.0e9f ? (uint32_t)steps : 1000000000u) : 1u;
}

static void build_layout(hd_kf_t *kf)
{
    unsigned enabled = 0;
    kf->motor_powers = 0u;
    kf->output_powers = 0u;
    kf->own_frames = 0u;
    kf->profiled_slots = 0u; /* build_slot: every slot at q_motion_ref_rad */
    kf->nyquist_limit_rad = kf->cfg.nyquist_fraction * HD_PI_F;
    kf->jump_rearm_steps = steps_of(HD_KF_JUMP_REARM_S, kf->cfg.ts_s);
    kf->limit_restart_steps = steps_of(HD_KF_LIMIT_RESTART_S, kf->cfg.ts_s);
    kf->drift_hold_total = steps_of(HD_KF_DRIFT_HOLD_S, kf->cfg.ts_s);
    kf->follow_settle_total = steps_of(HD_KF_FOLLOW_SETTLE_S, kf->cfg.ts_s);
    for (unsigned i = 0; i < kf->cfg.block_count; i++) {
        build_slot(kf, i);
        enabled += kf->slot[i].enabled;
    }
    kf->n_blocks = (uint8_t)(kf->cfg.block_count < MIN_LAYOUT_BLOCKS ? MIN_LAYOUT_BLOCKS
                             : kf->cfg.block_count <= UNROLLED_BLOCKS ? kf->cfg.block_count
                                                                      : HD_KF_MAX_BLOCKS);
    for (unsigned i = kf->cfg.block_count; i < kf->n_blocks; i++) {
        kf->slot[i] = (hd_kf_slot_t){0};
    }
    kf->offset_slot = (uint8_t)(2u * kf->n_blocks);
    kf->n_states = (uint8_t)(2u * enabled + (kf->cfg.offset_enabled ? 1u : 0u));
    kf->offset_q_nm2 = kf->cfg.offset_enabled ? kf->cfg.offset_q_nm2 : 0.0f;
    kf->q_motion_inv_rad = kf->cfg.q_motion_ref_rad > 0.0f ? 1.0f / kf->cfg.q_motion_ref_rad
                                                            : 0.0f;
    short_plan_ranges(kf);
    kf->output_follow = (kf->cfg.output_row_follow > 0.0f && kf->cfg.output_learn_scale == 0.0f)
                            ? 1u : 0u;
    kf->output_row_alpha = kf->cfg.ts_s < HD_KF_OUTPUT_ROW_TAU_S
                               ? kf->cfg.ts_s / HD_KF_OUTPUT_ROW_TAU_S : 1.0f;
}

void hd_kf_follow_restart(hd_kf_t *kf)
{
    kf->output_row = 1.0f;
    kf->follow_primed = 0u;
    kf->follow_settle_steps = kf->follow_settle_total;
    kf->follow_mean_t = kf->follow_var_t = kf->follow_cov_tg = kf->follow_weight = 0.0f;
    kf->follow_mean_g = 1.0f;
}

void hd_kf_follow_reference(hd_kf_t *kf)
{
    float sum = 0.0f;
    for (unsigned i = 0; i < 2u * HD_KF_MAX_BLOCKS; i++) {
        sum += kf->motor_ref[i] * kf->motor_ref[i];
    }
    kf->motor_ref_inv = (sum > 0.0f && is_finite(sum)) ? 1.0f / sum : 0.0f;
}

/* Block s starts again: state zero, its tile v I, zero covariance with
 * every other state (its tile column above, its tile row and offset pair). */
void hd_kf_clear_block(hd_kf_t *kf, unsigned s, float v)
{
    const unsigned nb = kf->n_blocks;
    unsigned k = 4u * s - 1u; /* tile (0, s), when s > 0 */
    for (unsigned r = 0; r < s; r++) {
        zero_tiles(&kf->p[k], 1u);
        k += 4u * (nb - 1u - r) + 1u; /* to tile (r + 1, s) */
    }
    float *p = &kf->p[tile_row_start(nb, s)];
    p[0] = v;
    p[1] = 0.0f;
    p[2] = v;
    zero_tiles(p + 3, nb - 1u - s);
    p += 3u + 4u * (nb - 1u - s);
    p[0] = p[1] = 0.0f;
    kf->x[2u * s] = kf->x[2u * s + 1u] = 0.0f;
    keep_block_state(kf, s);
}

void hd_kf_reset(hd_kf_t *kf)
{
    const unsigned nb = kf->n_blocks;
    for (unsigned s = 0; s < nb; s++) {
        hd_kf_clear_block(kf, s, kf->slot[s].enabled ? kf->slot[s].p0_nm2 : 0.0f);
    }
    kf->p[packed_entries(nb) - 1u] = kf->cfg.offset_enabled ? kf->cfg.p0_nm2 : 0.0f;
    kf->x[kf->offset_slot] = 0.0f;
    kf->frozen_mask = 0u;
    kf->offset_primed = 0u;
    kf->jump_hold_steps = 0u;
    kf->jump_credit = HD_KF_JUMP_BURST;
    kf->event_angle_rad = kf->event_min_rad = kf->event_max_rad = 0.0f;
    kf->event_peak_nm2 = 0.0f;
    kf->limit_steps = 0u;
    kf->load_ref_primed = 0u;
    kf->load_ref_nm = 0.0f;
    kf->load_scale = 1.0f;
    for (unsigned i = 0; i < 2u * HD_KF_MAX_BLOCKS; i++) {
        kf->motor_ref[i] = 0.0f; /* the next profile import sets it again */
    }
    kf->motor_ref_inv = 0.0f;
    kf->follow_slots = 0u;
    kf->follow_load_nm = -1.0f;
    kf->learn_load_nm = kf->learn_load_weight = 0.0f;
    hd_kf_follow_restart(kf);
    hd_kf_profile_motion(kf, 0u); /* no line held any more */
    kf->drift_hold_steps = kf->drift_hold_total; /* the load unknown until the gate is quiet */
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
    /* The frames start at phase 0; a reset leaves them turning (x = 0 and
     * P = p0 I look the same in every frame). */
    for (unsigned i = 0; i < HD_KF_PHASORS; i++) {
        kf->phasor_cos[i] = 1.0f;
        kf->phasor_sin[i] = 0.0f;
    }
    kf->output_phase_hi_rad = 0.0f;
    kf->output_phase_lo_rad = 0.0f;
    kf->output_turns = 0u;
    hd_kf_reset(kf);
    kf->status_sticky = 0u;
    kf->reset_count = 0u;
    kf->bad_input_count = 0u;
    kf->p_ceiling_count = 0u;
    kf->p_negative_count = 0u;
    kf->jump_held_count = 0u;
    kf->limit_count = 0u;
    kf->rollback_count = 0u;
    kf->drift_count = 0u;
    kf->load_bound_count = 0u;
    return HD_KF_OK;
}

/* A disabled block keeps its slot with x = 0 and zero rows and columns of
 * P; the step gives it a zero row entry, no process noise and gain 1, so
 * g = P C' is exactly 0 on its states and nothing in the step changes them
 * or uses them (docs/design/filter.md, "Run-time block toggles"). */
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
    kf->cfg.blocks[block].enabled = enabled ? 1u : 0u;
    kf->slot[block].enabled = enabled ? 1u : 0u;
    hd_kf_clear_block(kf, block, enabled ? kf->slot[block].p0_nm2 : 0.0f);
    if (kf->cfg.q_motion_ref_profiled_rad > 0.0f) {
        set_motion_ref(kf, block, kf->cfg.q_motion_ref_rad,
                       kf->slot[block].full_shared_rad); /* its line is gone */
        kf->profiled_slots &= ~(1u << block);
    }
    short_plan_ranges(kf);
    kf->motor_ref[2u * block] = kf->motor_ref[2u * block + 1u] = 0.0f;
    kf->follow_slots &= ~(1u << block);
    hd_kf_follow_reference(kf);
    kf->n_states = (uint8_t)(enabled ? kf->n_states + 2u : kf->n_states - 2u);
    kf->frozen_mask &= ~(1u << block);
    return HD_KF_OK;
}
