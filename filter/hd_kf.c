/* hd_kf: see hd_kf.h for the contracts, docs/filter.md for the design. */
#include "hd_kf.h"

#include <math.h> /* sqrtf (VSQRT on Cortex-M4F): clamp and read-out; atan2f: read-out only */
#include <stddef.h>

#include "hd_trig.h"

#define DEFAULT_R_NM2 1.0f
#define DEFAULT_P0_NM2 0.3f /* an amplitude prior (docs/filter.md, "Priors") */
#define DEFAULT_P_MAX_NM2 1.0e6f
#define DEFAULT_NYQUIST_FRACTION 0.9f
#define DEFAULT_OFFSET_Q_NM2 1.0e-6f
#define DEFAULT_OUTPUT_LEARN_SCALE 1.0f
#define RECOMMENDED_Q_MOTION_REF_RAD 0.05f
#define RECOMMENDED_OUTPUT_P0_NM2 0.01f
#define PAPER_Q_NM2 1.0e3f
#define PAPER_R_NM2 1.0f
#define RECOMMENDED_JUMP_NOISE_MULTIPLE 25.0f
#define JUMP_MIN_SIGMA 4.0f
/* Integral orders up to this take powers of the lock's phasor (doubling
 * depth <= 3: angle within 2e-7 rad, docs/filter.md). */
#define MAX_POWER_ORDER ((unsigned)HD_KF_MAX_POWER)
/* Phasor table: motor powers at [1, 8], output powers at [10, 17], then one
 * per configured block that turns its own frame. */
#define POWER_TABLE_OUTPUT (MAX_POWER_ORDER + 1u)
#define OWN_PHASORS (2u * POWER_TABLE_OUTPUT)
/* Below this |angle| [rad] sine and cosine come from their series
 * a - a^3/6 and 1 - a^2/2 + a^4/24: the next terms are < 1e-8 relative,
 * under float32 rounding. */
#define SMALL_ANGLE_RAD 0.03125f
#define PROFILE_MAX_ORDER 255.0f
/* Steps the output phasor turns by increments before it is set again from
 * the exactly accumulated output phase. */
#define OUTPUT_TURNS_MAX 256u

/* The step's kernels are written once with loops over the blocks and
 * instantiated per layout size, where every loop unrolls (docs/filter.md,
 * "Instances per layout size"). */
#define KF_INLINE static inline __attribute__((always_inline))
#define KF_UNROLL _Pragma("GCC unroll 8")
/* The slow paths out of the way of the straight one. */
#define UNLIKELY(cond) __builtin_expect(!!(cond), 0)
/* Layouts of MIN_LAYOUT_BLOCKS to UNROLLED_BLOCKS blocks have their own
 * instance; smaller models take the smallest, larger ones HD_KF_MAX_BLOCKS
 * slots, the unused slots held at zero like a disabled block. */
#define MIN_LAYOUT_BLOCKS (HD_KF_MAX_BLOCKS < 2 ? HD_KF_MAX_BLOCKS : 2u)
#define UNROLLED_BLOCKS 4u

typedef union {
    float f;
    uint32_t u;
} float_bits_t;

#define FLOAT_SIGN_BIT 0x80000000u
#define FLOAT_INF_BITS 0x7f800000u
/* 2 pi as hi + lo: hi has 16 significant bits, so hi's multiples and
 * differences near pi are exact. */
#define TWO_PI_HI 6.28125f
#define TWO_PI_LO 1.9353071795864769e-3f

/* isfinite without libm calls; x - x is 0 only for finite x. */
static bool is_finite(float x)
{
    return (x - x) == 0.0f;
}

static uint32_t bits_of(float x)
{
    const float_bits_t b = {.f = x};
    return b.u;
}

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
    if (!is_nonneg(cfg->output_learn_scale) || cfg->output_learn_scale > 1.0f) {
        return HD_KF_ERR_LEARN_SCALE;
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
        "FROZEN", "BAD_INPUT", "RESET", "P_CLAMPED", "OFFSET_JUMP"};
    return bit < HD_KF_STATUS_BITS ? NAMES[bit] : NULL;
}

/* ===================================================================== */
/* Layout: slots, frames and the packed covariance                        */
/* ===================================================================== */

/* P is stored once, by 2x2 tiles of the upper triangle, tile row by tile
 * row.  Tile row s (block slot s, states 2s and 2s+1) holds
 *   its diagonal tile      P(2s,2s) P(2s,2s+1) P(2s+1,2s+1)
 *   tiles (s, t), t > s    P(2s,2t) P(2s,2t+1) P(2s+1,2t) P(2s+1,2t+1)
 *   the offset column      P(2s,o)  P(2s+1,o)
 * and P(o,o) comes last.  Each pass of the step walks it front to back.
 * Every configured block has its slot (slot s = configured block s), and
 * the offset its column even when it is disabled: then its state, q and
 * covariances are zero and stay zero. */
KF_INLINE unsigned tile_row_start(unsigned nb, unsigned s)
{
    return s * (3u + 4u * nb - 2u * s);
}

static unsigned packed_entries(unsigned nb)
{
    return tile_row_start(nb, nb) + 1u;
}

/* Packed position of P(i, j), i and j layout states (block slots, offset
 * at 2 nb). */
static unsigned packed_index(unsigned nb, unsigned i, unsigned j)
{
    if (i > j) {
        const unsigned t = i;
        i = j;
        j = t;
    }
    const unsigned si = i >> 1u;
    if (i == 2u * nb) {
        return tile_row_start(nb, nb);
    }
    const unsigned row = tile_row_start(nb, si);
    if (j == 2u * nb) {
        return row + 3u + 4u * (nb - 1u - si) + (i & 1u);
    }
    const unsigned sj = j >> 1u;
    if (si == sj) {
        return row + (i & 1u) + (j & 1u);
    }
    return row + 3u + 4u * (sj - si - 1u) + 2u * (i & 1u) + (j & 1u);
}

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

static void build_slot(hd_kf_t *kf, unsigned block)
{
    const hd_kf_block_config_t *b = &kf->cfg.blocks[block];
    hd_kf_slot_t *sl = &kf->slot[block];
    const bool motion_scaled = kf->cfg.q_motion_ref_rad > 0.0f && b->lock != HD_KF_LOCK_FIXED;
    *sl = (hd_kf_slot_t){0};
    sl->lock = b->lock;
    sl->enabled = b->enabled ? 1u : 0u;
    sl->theta_per_unit = b->order;
    sl->motion_inv = motion_scaled ? 1.0f / kf->cfg.q_motion_ref_rad : 0.0f;
    sl->motion_bias = motion_scaled ? 0.0f : 1.0f;
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
    if (b->lock == HD_KF_LOCK_MOTOR) {
        sl->full_rad = first_float(kf, sl, motion_full);
    }
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

/* Builds every configured block's slot and the per-step constants.  A
 * model of more than UNROLLED_BLOCKS blocks gets HD_KF_MAX_BLOCKS slots,
 * the unused ones disabled. */
static void build_layout(hd_kf_t *kf)
{
    unsigned enabled = 0;
    kf->motor_powers = 0u;
    kf->output_powers = 0u;
    kf->own_frames = 0u;
    kf->nyquist_limit_rad = kf->cfg.nyquist_fraction * HD_PI_F;
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
}

/* Zeroes n tiles of 4 from p (written tile by tile: GCC turns a plain
 * zeroing loop into a memset call, which the bare-metal boards provide
 * byte by byte). */
KF_INLINE void zero_tiles(float *p, unsigned n)
{
    for (; n > 0u; n--, p += 4) {
        p[0] = p[1] = p[2] = p[3] = 0.0f;
    }
}

/* Block s starts again: state zero, its tile v I, zero covariance with
 * every other state (its tile column above, its tile row and offset pair). */
static void clear_block(hd_kf_t *kf, unsigned s, float v)
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
}

void hd_kf_reset(hd_kf_t *kf)
{
    const unsigned nb = kf->n_blocks;
    for (unsigned s = 0; s < nb; s++) {
        clear_block(kf, s, kf->slot[s].enabled ? kf->slot[s].p0_nm2 : 0.0f);
    }
    kf->p[packed_entries(nb) - 1u] = kf->cfg.offset_enabled ? kf->cfg.p0_nm2 : 0.0f;
    kf->x[kf->offset_slot] = 0.0f;
    kf->frozen_mask = 0u;
    kf->offset_primed = 0u;
    kf->load_ref_primed = 0u;
    kf->load_ref_nm = 0.0f;
    kf->load_scale = 1.0f;
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
    return HD_KF_OK;
}

/* A disabled block keeps its slot with x = 0 and zero rows and columns of
 * P; the step gives it a zero row entry, no process noise and gain 1, so
 * g = P C' is exactly 0 on its states and nothing in the step changes them
 * or uses them (docs/filter.md, "Run-time block toggles"). */
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
    clear_block(kf, block, enabled ? kf->slot[block].p0_nm2 : 0.0f);
    short_plan_ranges(kf);
    kf->n_states = (uint8_t)(enabled ? kf->n_states + 2u : kf->n_states - 2u);
    kf->frozen_mask &= ~(1u << block);
    return HD_KF_OK;
}

/* ===================================================================== */
/* The step                                                               */
/* ===================================================================== */

/* sin and cos of a small angle (|a| <= SMALL_ANGLE_RAD) by the series
 * a - a^3/6 and 1 - a^2/2 + a^4/24: the next terms are < 1e-8 relative. */
KF_INLINE void sincos_series(float a, float *s, float *c)
{
    const float a2 = a * a;
    *s = a - a * a2 * (1.0f / 6.0f);
    *c = 1.0f - a2 * (0.5f - a2 * (1.0f / 24.0f));
}

/* sin and cos of one step's angle: the unreduced polynomials below
 * HD_TRIG_NO_REDUCTION_RAD (the bits hd_sincosf gives there), hd_sincosf
 * beyond. */
KF_INLINE void sincos_step(float a, float *s, float *c)
{
    if (fabsf(a) < HD_TRIG_NO_REDUCTION_RAD) {
        *s = hd_sin_poly(a);
        *c = hd_cos_poly(a);
    } else {
        hd_sincosf(a, s, c);
    }
}

/* The motion fraction min(1, |angle| / q_motion_ref_rad); 1 when off. */
static float motion_fraction(const hd_kf_t *kf, float angle_rad)
{
    const float a = fabsf(angle_rad);
    return (kf->q_motion_inv_rad <= 0.0f || a >= kf->cfg.q_motion_ref_rad)
               ? 1.0f
               : a * kf->q_motion_inv_rad;
}

/* Measurement-row scale of motor-locked blocks with k > 0: 1 + k |T_ref|,
 * with T_ref following T_exp (+ the offset when it is real torque) by the
 * motor's motion fraction, held at standstill.  |T_ref| is capped at
 * HD_KF_MAX_ABS_Y_NM so the entry stays finite. */
static float update_load_scale(hd_kf_t *kf, float torque_expected_nm, float d_motor_rad)
{
    float t_now = is_finite(torque_expected_nm) ? torque_expected_nm : 0.0f;
    if (kf->cfg.offset_enabled && !kf->cfg.offset_is_sensor_error && kf->offset_primed) {
        t_now += kf->x[kf->offset_slot];
    }
    if (!kf->load_ref_primed) {
        kf->load_ref_nm = t_now;
        kf->load_ref_primed = 1u;
    } else {
        kf->load_ref_nm += motion_fraction(kf, d_motor_rad) * (t_now - kf->load_ref_nm);
    }
    const float t = fabsf(kf->load_ref_nm);
    return 1.0f + kf->cfg.ripple_load_coeff_per_nm * (t < HD_KF_MAX_ABS_Y_NM ? t : HD_KF_MAX_ABS_Y_NM);
}

/* The step's probes: a block tile with trace in [0, p_max] and
 * determinant >= 0 has both model-coordinate diagonals in [0, p_max]
 * whatever its frame; the sum of the traces (and P_oo) is compared with
 * p_max (not a number fails too), the sign bits of every trace,
 * determinant and P_oo are ORed. */
typedef struct {
    float traces;   /* sum of the block traces and P_oo */
    uint32_t signs; /* OR of the bit patterns of traces, determinants, P_oo */
} bound_probe_t;

/* The step's inputs as the blocks see them: increments and row scales by
 * lock. */
typedef struct {
    float inc[3];          /* motor, output, 1 (the fixed blocks' unit) */
    float rows[3];         /* measurement-row scale: 1 + k |T_ref|, 1, 1 */
    uint32_t short_slots;  /* the motor blocks' short plan (every enabled motor
                              block at motion 1, none frozen): their slots */
    uint32_t free_slots;   /* the output blocks' (none frozen): their slots */
} step_io_t;

/* What the plan of the blocks adds up. */
typedef struct {
    float ripple;          /* prior ripple C x (without the offset) */
    uint32_t partial;      /* blocks with a gain fraction below 1 */
    uint32_t frozen;       /* by configured block */
    uint32_t lost;         /* phase lost: restart */
} plan_sum_t;

/* Block s's part of this step: measurement row h (in its frame: c (cos phi,
 * sin phi), 0 when frozen or disabled), gain fraction f and process noise q
 * per state.  A disabled block gets a zero row, no q and gain 1 (its
 * states and covariances are zero: no weight applies to them). */
KF_INLINE void plan_block(const hd_kf_t *kf, unsigned s, const step_io_t *io, float *h,
                          float *f, float *q, plan_sum_t *sum)
{
    const hd_kf_slot_t *sl = &kf->slot[s];
    if ((io->short_slots & (1u << s)) != 0u) {
        /* what the rules below give at motion 1, not frozen */
        const float row = io->rows[HD_KF_LOCK_MOTOR];
        h[0] = row * kf->phasor_cos[sl->frame];
        h[1] = row * kf->phasor_sin[sl->frame];
        *f = 1.0f;
        *q = sl->q_nm2;
        sum->ripple += h[0] * kf->x[2u * s];
        sum->ripple += h[1] * kf->x[2u * s + 1u];
        return;
    }
    if ((io->free_slots & (1u << s)) != 0u) {
        /* an output block not frozen: its row entry is 1, its gain learn
         * (partial slots: set by the caller) */
        const float a = fabsf(sl->theta_per_unit * io->inc[HD_KF_LOCK_OUTPUT]);
        const float motion = a * sl->motion_inv + sl->motion_bias;
        h[0] = kf->phasor_cos[sl->frame];
        h[1] = kf->phasor_sin[sl->frame];
        *f = sl->learn;
        *q = sl->q_nm2 * (motion < 1.0f ? motion : 1.0f);
        sum->ripple += h[0] * kf->x[2u * s];
        sum->ripple += h[1] * kf->x[2u * s + 1u];
        return;
    }
    if (UNLIKELY(!sl->enabled)) {
        h[0] = h[1] = *q = 0.0f;
        *f = 1.0f;
        return;
    }
    const unsigned lock = sl->lock;
    const float a = fabsf(sl->theta_per_unit * io->inc[lock]);
    float motion = a * sl->motion_inv + sl->motion_bias;
    motion = motion < 1.0f ? motion : 1.0f;
    /* a motor block learns as it turns; learn is 1 for motor blocks */
    float gain = lock == HD_KF_LOCK_MOTOR ? motion : sl->learn;
    float qs = sl->q_nm2 * motion;
    float row = io->rows[lock];
    if (UNLIKELY(!(a <= kf->nyquist_limit_rad))) {
        /* Held: not observed, not corrected, no process noise, still
         * turned by the increment (exact at any speed), unless no motion
         * can explain it (an encoder fault). */
        sum->frozen |= 1u << s;
        gain = qs = row = 0.0f;
        if (!(a <= HD_KF_PHASE_LOST_RAD)) {
            sum->lost |= 1u << s;
        }
    }
    if (gain < 1.0f) {
        sum->partial |= 1u << s;
    }
    h[0] = row * kf->phasor_cos[sl->frame];
    h[1] = row * kf->phasor_sin[sl->frame];
    *f = gain;
    *q = qs;
    sum->ripple += h[0] * kf->x[2u * s];
    sum->ripple += h[1] * kf->x[2u * s + 1u];
}

/* g = (P + Q) C' over the packed tiles, P + Q being the prior's
 * covariance (Q is diagonal: it is added to the diagonal tiles as they are
 * read, and stored by correct); returns C (P + Q) C'.  Each off-diagonal
 * tile adds to both its rows' and its columns' entries of g; sums
 * accumulate term by term (one multiply-accumulate each), rows above
 * first.  The offset's row entry is 1. */
KF_INLINE float cross_covariance(const float *restrict p, const float *restrict h,
                                 const float *restrict q, float q_off, float *restrict g,
                                 unsigned nb)
{
    float acc[2u * HD_KF_MAX_BLOCKS + 1u]; /* column sums of the rows above */
    float g_off = 0.0f, cpc = 0.0f;
    KF_UNROLL
    for (unsigned s = 0; s < nb; s++) {
        const float h0 = h[2u * s], h1 = h[2u * s + 1u];
        const float pa = p[0] + q[s], pd = p[2] + q[s];
        float ga = s == 0u ? pa * h0 : acc[2u * s] + pa * h0;
        float gb = s == 0u ? p[1] * h0 : acc[2u * s + 1u] + p[1] * h0;
        ga += p[1] * h1;
        gb += pd * h1;
        p += 3;
        KF_UNROLL
        for (unsigned t = s + 1u; t < nb; t++, p += 4) {
            const float k0 = h[2u * t], k1 = h[2u * t + 1u];
            ga += p[0] * k0;
            ga += p[1] * k1;
            gb += p[2] * k0;
            gb += p[3] * k1;
            float t0 = s == 0u ? p[0] * h0 : acc[2u * t] + p[0] * h0;
            float t1 = s == 0u ? p[1] * h0 : acc[2u * t + 1u] + p[1] * h0;
            t0 += p[2] * h1;
            t1 += p[3] * h1;
            acc[2u * t] = t0;
            acc[2u * t + 1u] = t1;
        }
        ga += p[0];
        gb += p[1];
        g_off += p[0] * h0;
        g_off += p[1] * h1;
        p += 2;
        g[2u * s] = ga;
        g[2u * s + 1u] = gb;
        cpc += h0 * ga;
        cpc += h1 * gb;
    }
    g_off += p[0] + q_off;
    cpc += g_off;
    g[2u * nb] = g_off;
    return cpc;
}

/* A block's diagonal tile [a b; b d]: Q added (the prior), downdate with
 * weights (wa, wb), into the probe. */
KF_INLINE void correct_diag_tile(float *p, float wa, float wb, float ga, float gb, float q,
                                 bound_probe_t *probe)
{
    const float a = (p[0] + q) - wa * ga, b = p[1] - wa * gb;
    const float d = (p[2] + q) - wb * gb;
    p[0] = a;
    p[1] = b;
    p[2] = d;
    const float trace = a + d;
    probe->traces += trace;
    probe->signs |= bits_of(trace) | bits_of(a * d - b * b);
}

/* A block's unchanged diagonal tile into the probe. */
KF_INLINE void probe_diag_tile(const float *p, bound_probe_t *probe)
{
    const float trace = p[0] + p[2];
    probe->traces += trace;
    probe->signs |= bits_of(trace) | bits_of(p[0] * p[2] - p[1] * p[1]);
}

/* The Joseph tiles: tile (s, t) with W_st = f_s + f_t - f_s f_t below 1,
 * i.e. both blocks' fractions below 1 (partial), which the unrolled pass
 * leaves; the weight is 1 wherever one of the fractions is 1.  A frozen
 * block's fraction is 0: W is 0 between two frozen blocks (those tiles and
 * a frozen block's own, which gets no q either, stay as they are). */
static void correct_partial(float *p, const float *g, const float *f, const float *q,
                            float inv_s, unsigned nb, uint32_t partial, uint32_t frozen,
                            bound_probe_t *probe)
{
    for (uint32_t rows = partial; rows != 0u; rows &= rows - 1u) {
        const unsigned s = (unsigned)__builtin_ctz(rows);
        float *row = &p[tile_row_start(nb, s)];
        const float fs = f[s], ga = g[2u * s], gb = g[2u * s + 1u];
        const float ua = ga * inv_s, ub = gb * inv_s;
        uint32_t cols = partial & ~((2u << s) - 1u);
        if ((frozen & (1u << s)) != 0u) {
            probe_diag_tile(row, probe);
            cols &= ~frozen;
        } else {
            const float ws = fs + fs - fs * fs;
            correct_diag_tile(row, ws * ua, ws * ub, ga, gb, q[s], probe);
        }
        for (; cols != 0u; cols &= cols - 1u) {
            const unsigned t = (unsigned)__builtin_ctz(cols);
            float *tile = row + 3u + 4u * (t - s - 1u);
            const float w = fs + f[t] - fs * f[t];
            const float wa = w * ua, wb = w * ub;
            tile[0] -= wa * g[2u * t];
            tile[1] -= wa * g[2u * t + 1u];
            tile[2] -= wb * g[2u * t];
            tile[3] -= wb * g[2u * t + 1u];
        }
    }
}

/* x <- x + F g k_e and P <- (P + Q) - W .* g g' / S in the frames, where
 * the step's rotation is only a turn of the frames (advance_frames), so P + Q
 * is the prior's covariance: each tile loaded once, Q added, downdated,
 * stored once.  W_st = f_s + f_t - f_s f_t
 * (the Joseph form for the gain F g / S) is 1 unless both fractions are
 * below 1 (the offset's fraction is 1): those tiles, in partial, are left to
 * correct_partial.  inv_s = k_e = 0: prediction only. */
KF_INLINE void correct(float *restrict p, float *restrict x, const float *restrict g,
                       const float *restrict f, const float *restrict q, float inv_s, float k_e,
                       float q_off, unsigned nb, uint32_t partial, uint32_t frozen,
                       bound_probe_t *probe)
{
    float *const p_start = p;
    const float g_off = g[2u * nb];
    bound_probe_t worst = {0.0f, 0u};
    KF_UNROLL
    for (unsigned s = 0; s < nb; s++, x += 2) {
        const float ga = g[2u * s], gb = g[2u * s + 1u];
        const float fk = f[s] * k_e;
        x[0] += ga * fk;
        x[1] += gb * fk;
        const float ua = ga * inv_s, ub = gb * inv_s;
        if ((partial & (1u << s)) == 0u) {
            correct_diag_tile(p, ua, ub, ga, gb, q[s], &worst);
        }
        p += 3;
        KF_UNROLL
        for (unsigned t = s + 1u; t < nb; t++, p += 4) {
            const uint32_t both = (1u << s) | (1u << t);
            if ((partial & both) != both) {
                p[0] -= ua * g[2u * t];
                p[1] -= ua * g[2u * t + 1u];
                p[2] -= ub * g[2u * t];
                p[3] -= ub * g[2u * t + 1u];
            }
        }
        p[0] -= ua * g_off;
        p[1] -= ub * g_off;
        p += 2;
    }
    p[0] = (p[0] + q_off) - g_off * inv_s * g_off;
    worst.traces += p[0];
    worst.signs |= bits_of(p[0]);
    x[0] += g_off * k_e;
    if (UNLIKELY(partial != 0u)) {
        /* copies, so that g, f, q and worst stay in registers elsewhere */
        float gc[HD_KF_MAX_STATES], fc[HD_KF_MAX_BLOCKS], qc[HD_KF_MAX_BLOCKS];
        KF_UNROLL
        for (unsigned s = 0; s < nb; s++) {
            gc[2u * s] = g[2u * s];
            gc[2u * s + 1u] = g[2u * s + 1u];
            fc[s] = f[s];
            qc[s] = q[s];
        }
        bound_probe_t joseph = {0.0f, 0u};
        correct_partial(p_start, gc, fc, qc, inv_s, nb, partial, frozen, &joseph);
        worst.traces += joseph.traces;
        worst.signs |= joseph.signs;
    }
    *probe = worst;
}

/* Offset-jump gate: e beyond offset_jump_nm and 4 sigma. */
KF_INLINE bool offset_jump(const hd_kf_t *kf, float e, float s_var)
{
    const float jump_nm = kf->cfg.offset_jump_nm;
    const float e2 = e * e;
    return kf->cfg.offset_enabled && jump_nm > 0.0f && e2 > jump_nm * jump_nm &&
           e2 > JUMP_MIN_SIGMA * JUMP_MIN_SIGMA * s_var;
}

static void restart_lost_blocks(hd_kf_t *kf, uint32_t lost);

/* phase += d, kept as an unevaluated sum hi + lo in [-pi, pi) (Knuth's
 * two-sum): the increments add up exactly (to ~1e-14 rad) however long the
 * filter runs. */
KF_INLINE void add_phase(float *hi, float *lo, float d)
{
    const float h0 = *hi;
    const float s = h0 + d;
    const float bp = s - h0;
    const float err = (h0 - (s - bp)) + (d - bp);
    float h = s, l = *lo + err;
    if (UNLIKELY(!(fabsf(h) < HD_PI_F))) { /* one comparison on the common path */
        if (h >= HD_PI_F) {
            h -= TWO_PI_HI;
            l -= TWO_PI_LO;
        } else if (h < -HD_PI_F) {
            h += TWO_PI_HI;
            l += TWO_PI_LO;
        }
    }
    const float sum = h + l;
    *hi = sum;
    *lo = l - (sum - h);
}

/* z <- z w, then one Newton step towards |z| = 1 (scale (3 - |z|^2) / 2):
 * the phasors are advanced every step for as long as the filter runs, and
 * without it their magnitude would drift by the rounding of each product
 * (1e-5 within the 256 steps of the slow output phasor: the frames' read-out
 * in model coordinates would scale P by that). */
KF_INLINE void turn_phasor(float *c, float *s, float wc, float ws)
{
    const float nc = *c * wc - *s * ws;
    const float ns = *s * wc + *c * ws;
    const float scale = (3.0f - (nc * nc + ns * ns)) * 0.5f;
    *c = nc * scale;
    *s = ns * scale;
}

/* The motor phasor's turn without its Newton step, which normalize_motor
 * does once the step no longer needs the phasor (off the path from the
 * increment to the innovation; |z w| is within 2e-7 of 1 meanwhile). */
KF_INLINE void turn_phasor_raw(float *c, float *s, float wc, float ws)
{
    const float nc = *c * wc - *s * ws;
    const float ns = *s * wc + *c * ws;
    *c = nc;
    *s = ns;
}

KF_INLINE void normalize_phasor(float *c, float *s)
{
    const float scale = (3.0f - (*c * *c + *s * *s)) * 0.5f;
    *c *= scale;
    *s *= scale;
}

/* z^k for every k of mask (2..HD_KF_MAX_POWER) into pc/ps[k], from the
 * unit-length base z = pc/ps[1]: doubling for even k, one product with z
 * for odd k.  Recomputed from the base every step, so their rounding (angle
 * within 2e-7 rad of k u, |z^k| within 1e-7 of 1 for k <= 8) does not
 * accumulate. */
KF_INLINE void phasor_powers(uint32_t mask, float *restrict pc, float *restrict ps)
{
    KF_UNROLL
    for (unsigned k = 2u; k <= MAX_POWER_ORDER; k++) {
        if ((mask & (1u << k)) != 0u) {
            if (k % 2u == 0u) {
                const float sh = ps[k / 2u], ch = pc[k / 2u];
                pc[k] = 1.0f - 2.0f * sh * sh;
                ps[k] = 2.0f * sh * ch;
            } else {
                pc[k] = pc[k - 1u] * pc[1] - ps[k - 1u] * ps[1];
                ps[k] = ps[k - 1u] * pc[1] + pc[k - 1u] * ps[1];
            }
        }
    }
}

/* The output phasor's powers (rare: output orders above 1), out of line. */
static void output_phasor_powers(hd_kf_t *kf)
{
    phasor_powers(kf->output_powers, kf->phasor_cos + POWER_TABLE_OUTPUT,
                  kf->phasor_sin + POWER_TABLE_OUTPUT);
}

/* The output phasor from the exactly accumulated output phase: a slow
 * output (|increment| <= SMALL_ANGLE_RAD) turns by the series sin/cos,
 * cheaper than the sin/cos of the whole phase, and is set again from the
 * exact sum every OUTPUT_TURNS_MAX steps (the drift, < 3e-11 rad per step,
 * never accumulates); a faster one is set from the sum every step: sin/cos
 * of hi, then the first-order term in lo (|lo| <= 2.4e-7: the next term is
 * below 3e-14). */
KF_INLINE void advance_output_frame(hd_kf_t *kf, float d)
{
    float *c = &kf->phasor_cos[POWER_TABLE_OUTPUT + 1u];
    float *s = &kf->phasor_sin[POWER_TABLE_OUTPUT + 1u];
    add_phase(&kf->output_phase_hi_rad, &kf->output_phase_lo_rad, d);
    if (kf->output_turns < OUTPUT_TURNS_MAX && fabsf(d) <= SMALL_ANGLE_RAD) {
        float sn, cs;
        sincos_series(d, &sn, &cs);
        turn_phasor(c, s, cs, sn);
        kf->output_turns++;
    } else {
        const float lo = kf->output_phase_lo_rad;
        float sh, ch;
        hd_sincosf(kf->output_phase_hi_rad, &sh, &ch);
        *c = ch - lo * sh;
        *s = sh + lo * ch;
        kf->output_turns = 0u;
    }
}


/* The step's rotation Phi: each block's frame turns by its phase advance.
 * Integral orders take powers of the motor and output phasors; the others
 * turn their own.  The motor phasor turns by one sin/cos of the increment:
 * its rounding drifts the phase by ~2e-9 rad per step at constant speed
 * (docs/filter.md), which motor-locked blocks, learning all the time, take
 * up.  The output phasor comes from the exactly accumulated output phase:
 * an output-locked block that does not learn (output_learn_scale 0) keeps
 * its profile against the absolute angle for as long as the filter runs. */
KF_INLINE void advance_frames(hd_kf_t *kf, const float inc[3])
{
    if (kf->motor_powers != 0u) {
        float s, c;
        sincos_step(inc[HD_KF_LOCK_MOTOR], &s, &c);
        turn_phasor_raw(&kf->phasor_cos[1], &kf->phasor_sin[1], c, s);
        if ((kf->motor_powers & ~3u) != 0u) {
            phasor_powers(kf->motor_powers, kf->phasor_cos, kf->phasor_sin);
        }
    }
    if (kf->output_powers != 0u) {
        advance_output_frame(kf, inc[HD_KF_LOCK_OUTPUT]);
        if ((kf->output_powers & ~3u) != 0u) {
            output_phasor_powers(kf);
        }
    }
    for (uint32_t left = kf->own_frames; left != 0u; left &= left - 1u) {
        const hd_kf_slot_t *sl = &kf->slot[__builtin_ctz(left)];
        float sn = sl->fixed_sin, cs = sl->fixed_cos;
        if (sl->lock != HD_KF_LOCK_FIXED) {
            sincos_step(sl->theta_per_unit * inc[sl->lock], &sn, &cs);
        }
        turn_phasor(&kf->phasor_cos[sl->frame], &kf->phasor_sin[sl->frame], cs, sn);
    }
}

static uint32_t bound_covariance(hd_kf_t *kf, float finite_probe);

/* The step for a layout of nb blocks (a constant in each instance, so
 * every loop unrolls and h, g, f, q live in registers): inputs, the time
 * update by this sample's increments (the turn of the frames; its Q is
 * added in the passes over P), the plan of every block, restarts, offset
 * priming, the innovation and its variance against the prior, the offset
 * gate, the outputs, the measurement update and the bounds. */
KF_INLINE void step_layout(hd_kf_t *kf, const hd_kf_input_t *in, hd_kf_output_t *out,
                           unsigned nb)
{
    /* ---- inputs: a non-finite or absurd sample is not corrected; a
     * non-finite increment counts as no motion; the fixed blocks'
     * "increment" is 1 (their phase advance per step) */
    step_io_t io;
    io.inc[HD_KF_LOCK_MOTOR] = in->d_motor_angle_rad;
    io.inc[HD_KF_LOCK_OUTPUT] = in->d_output_angle_rad;
    io.inc[HD_KF_LOCK_FIXED] = 1.0f;
    const float y = in->torque_meas_nm - in->torque_expected_nm;
    const bool valid = fabsf(y) <= HD_KF_MAX_ABS_Y_NM;
    uint32_t status = valid ? 0u : HD_KF_STATUS_BAD_INPUT;
    if (UNLIKELY(!is_finite(io.inc[0] + io.inc[1]))) {
        for (unsigned i = 0; i < 2u; i++) {
            if (!is_finite(io.inc[i])) {
                io.inc[i] = 0.0f;
                status = HD_KF_STATUS_BAD_INPUT;
            }
        }
    }
    const float motor_abs = fabsf(io.inc[HD_KF_LOCK_MOTOR]);
    io.short_slots = motor_abs >= kf->motor_full_rad && motor_abs < kf->motor_frozen_rad
                         ? kf->motor_slots
                         : 0u;
    io.free_slots = fabsf(io.inc[HD_KF_LOCK_OUTPUT]) < kf->output_frozen_rad ? kf->output_slots
                                                                            : 0u;
    const float c_load = kf->cfg.ripple_load_coeff_per_nm > 0.0f
                             ? update_load_scale(kf, in->torque_expected_nm,
                                                 io.inc[HD_KF_LOCK_MOTOR])
                             : 1.0f;
    io.rows[HD_KF_LOCK_MOTOR] = c_load;
    io.rows[HD_KF_LOCK_OUTPUT] = io.rows[HD_KF_LOCK_FIXED] = 1.0f;

    /* ---- time update: the posterior of the last sample turns by this
     * sample's increments (Phi is a turn of the frames; the plan below
     * reads the turned ones) */
    advance_frames(kf, io.inc);

    /* ---- what this step does to each block */
    float h[2u * HD_KF_MAX_BLOCKS], f[HD_KF_MAX_BLOCKS], q[HD_KF_MAX_BLOCKS];
    float g[HD_KF_MAX_STATES];
    plan_sum_t sum = {0.0f, io.free_slots & kf->output_partial_slots, 0u, 0u};
    KF_UNROLL
    for (unsigned s = 0; s < nb; s++) {
        plan_block(kf, s, &io, &h[2u * s], &f[s], &q[s], &sum);
    }
    if (UNLIKELY(sum.lost != 0u)) {
        restart_lost_blocks(kf, sum.lost);
    }

    /* ---- innovation and its variance (the prior's) */
    const float ripple = sum.ripple;
    const unsigned o = 2u * nb;
    if (UNLIKELY(!kf->offset_primed) && kf->cfg.offset_enabled && valid) {
        kf->x[o] = y - ripple;
        kf->offset_primed = 1u;
    }
    const float offset = kf->x[o]; /* 0 when the offset is disabled */
    float s_var = kf->cfg.r_nm2 + cross_covariance(kf->p, h, q, kf->offset_q_nm2, g, nb);
    const float innovation = y - ripple - offset;
    if (UNLIKELY(valid && offset_jump(kf, innovation, s_var))) {
        /* an offset jump widens the offset's variance first */
        const float e2 = innovation * innovation;
        status |= HD_KF_STATUS_OFFSET_JUMP;
        kf->p[packed_entries(nb) - 1u] += e2;
        g[o] += e2;
        s_var += e2;
    }

    /* ---- outputs */
    out->ripple_nm = ripple;
    out->offset_nm = offset;
    out->innovation_nm = valid ? innovation : 0.0f;
    out->innovation_var_nm2 = s_var;
    const float filtered = in->torque_meas_nm - ripple -
                           (kf->cfg.offset_is_sensor_error ? offset : 0.0f);
    out->torque_filtered_nm = filtered;
    out->frozen_mask = sum.frozen;

    /* ---- correct; bounds on the slow path */
    const float inv_s = valid ? 1.0f / s_var : 0.0f;
    const float k_e = valid ? innovation * inv_s : 0.0f;
    /* S is not finite when some g is not (each enters C P C'), the ripple
     * when some state is not: then neither are the new states */
    const float finite_probe = ripple + offset + s_var + k_e;
    bound_probe_t probe;
    correct(kf->p, kf->x, g, f, q, inv_s, k_e, kf->offset_q_nm2, nb, sum.partial, sum.frozen,
            &probe);
    kf->frozen_mask = sum.frozen;
    kf->load_scale = c_load;
    normalize_phasor(&kf->phasor_cos[1], &kf->phasor_sin[1]); /* (1, 0) if unused: kept */
    if (UNLIKELY(!(probe.traces <= kf->cfg.p_max_nm2) || (probe.signs & FLOAT_SIGN_BIT) != 0u ||
                 !is_finite(finite_probe))) {
        const uint32_t bounded = bound_covariance(kf, finite_probe);
        if (bounded & HD_KF_STATUS_RESET) {
            hd_kf_reset(kf);
            kf->reset_count++;
        }
        status |= bounded;
    }
    if (sum.frozen != 0u) {
        status |= HD_KF_STATUS_FROZEN;
    }
    if (status & HD_KF_STATUS_BAD_INPUT) {
        kf->bad_input_count++;
    }
    out->status = status;
    kf->status_sticky |= status;
    if (UNLIKELY(!is_finite(filtered))) {
        /* Never publish a non-finite estimate: fall back to the measurement
         * (or 0 if that is not finite either). */
        out->torque_filtered_nm = is_finite(in->torque_meas_nm) ? in->torque_meas_nm : 0.0f;
        out->ripple_nm = 0.0f;
    }
}

/* One instance per layout size (build_layout). */
#define STEP_INSTANCE(NAME, N)                                                     \
    static __attribute__((noinline)) void step_##NAME(hd_kf_t *kf, const hd_kf_input_t *in, \
                                                      hd_kf_output_t *out)         \
    {                                                                              \
        step_layout(kf, in, out, (N) < HD_KF_MAX_BLOCKS ? (N) : HD_KF_MAX_BLOCKS); \
    }
STEP_INSTANCE(2, 2u)
STEP_INSTANCE(3, 3u)
STEP_INSTANCE(4, 4u)
STEP_INSTANCE(max, HD_KF_MAX_BLOCKS)

/* Phase lost: the blocks restart from zero with their priors,
 * decorrelated; one pass over P for all of them. */
static void restart_lost_blocks(hd_kf_t *kf, uint32_t lost)
{
    const unsigned nb = kf->n_blocks;
    float *p = kf->p;
    for (unsigned s = 0; s < nb; s++) {
        const bool row = (lost & (1u << s)) != 0u;
        if (row) {
            p[0] = p[2] = kf->slot[s].p0_nm2;
            p[1] = 0.0f;
            kf->x[2u * s] = kf->x[2u * s + 1u] = 0.0f;
        }
        p += 3;
        for (unsigned t = s + 1u; t < nb; t++, p += 4) {
            if (row || (lost & (1u << t)) != 0u) {
                zero_tiles(p, 1u);
            }
        }
        if (row) {
            p[0] = p[1] = 0.0f;
        }
        p += 2;
    }
}

/* The scale of a variance v against the ceiling: 1 inside [0, p_max],
 * sqrt(p_max / v) above it (counted), 0 below 0 (counted); -1 when v is
 * not a number. */
KF_INLINE float ceiling_scale(hd_kf_t *kf, float v)
{
    const float p_max = kf->cfg.p_max_nm2;
    if (!is_finite(v)) {
        return -1.0f;
    }
    if (v < 0.0f) {
        kf->p_negative_count++;
        return 0.0f;
    }
    if (v > p_max) {
        kf->p_ceiling_count++;
        return sqrtf(p_max / v);
    }
    return 1.0f;
}

/* Slow path, when the probe saw a block or the offset leave the bounds or
 * the state was not finite: a non-finite state or covariance resets the
 * filter; otherwise P <- D P D, D = sqrt(p_max / lambda_max) on both states
 * of a block whose largest eigenvalue is above p_max (the same in every
 * frame, so it is applied in the frames), sqrt(p_max / P_oo) on the
 * offset, and 0 on a block that is not PSD or a negative offset variance.
 * Returns the status bits raised. */
static uint32_t bound_covariance(hd_kf_t *kf, float finite_probe)
{
    const unsigned nb = kf->n_blocks;
    float d[HD_KF_MAX_BLOCKS + 1u];
    bool scaled = false;
    if (!is_finite(finite_probe)) {
        return HD_KF_STATUS_RESET;
    }
    float *p = kf->p;
    for (unsigned s = 0; s < nb; s++) {
        const float mid = (p[0] + p[2]) * 0.5f, half = (p[0] - p[2]) * 0.5f;
        const float det = p[0] * p[2] - p[1] * p[1];
        const float lmax = mid + sqrtf(half * half + p[1] * p[1]);
        d[s] = ceiling_scale(kf, (det < 0.0f || mid < 0.0f) ? -1.0f : lmax);
        if (!is_finite(lmax + det)) {
            return HD_KF_STATUS_RESET;
        }
        scaled |= d[s] != 1.0f;
        p += 5u + 4u * (nb - 1u - s);
    }
    d[nb] = ceiling_scale(kf, p[0]);
    if (d[nb] < 0.0f) {
        return HD_KF_STATUS_RESET;
    }
    scaled |= d[nb] != 1.0f;
    if (!scaled) {
        return 0u;
    }
    p = kf->p;
    for (unsigned s = 0; s < nb; s++) {
        const float ds = d[s];
        p[0] *= ds * ds;
        p[1] *= ds * ds;
        p[2] *= ds * ds;
        p += 3;
        for (unsigned t = s + 1u; t < nb; t++, p += 4) {
            const float w = ds * d[t];
            p[0] *= w;
            p[1] *= w;
            p[2] *= w;
            p[3] *= w;
        }
        p[0] *= ds * d[nb];
        p[1] *= ds * d[nb];
        p += 2;
    }
    p[0] *= d[nb] * d[nb];
    return HD_KF_STATUS_P_CLAMPED;
}

void hd_kf_step(hd_kf_t *kf, const hd_kf_input_t *in, hd_kf_output_t *out)
{
    switch (kf->n_blocks) {
    case 2: step_2(kf, in, out); break;
    case 3: step_3(kf, in, out); break;
    case 4: step_4(kf, in, out); break;
    default: step_max(kf, in, out); break;
    }
}

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
    return kf->slot[block].lock == HD_KF_LOCK_MOTOR ? kf->load_scale : 1.0f;
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
        prior_var_nm2 > kf->cfg.p_max_nm2) {
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
    clear_block(kf, s, var_nm2);
    const unsigned f = kf->slot[s].frame;
    const float c = kf->phasor_cos[f], sn = kf->phasor_sin[f];
    /* the frame's R' takes the model's coordinates into the frame */
    kf->x[2u * s] = c * x1 - sn * x2;
    kf->x[2u * s + 1u] = sn * x1 + c * x2;
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
    return count;
}
