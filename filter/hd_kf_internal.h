/* hd_kf_internal: what the filter's source files share (hd_kf.c:
 * configuration, layout, init; hd_kf_step.c: the step; hd_kf_rows.c: its
 * load-dependent rows; hd_kf_bounds.c: its
 * slow paths; hd_kf_readout.c: read-out and profiles).  Private to filter/. */
#ifndef HD_KF_INTERNAL_H
#define HD_KF_INTERNAL_H

#include <stdbool.h>
#include <stdint.h>

#include "hd_kf.h"
#include "hd_float.h"

/* Integral orders up to this take powers of the lock's phasor (doubling
 * depth <= 3: angle within 2e-7 rad, docs/design/filter.md). */
#define MAX_POWER_ORDER ((unsigned)HD_KF_MAX_POWER)
/* Phasor table: motor powers at [1, 8], output powers at [10, 17], then one
 * per configured block that turns its own frame. */
#define POWER_TABLE_OUTPUT (MAX_POWER_ORDER + 1u)
#define OWN_PHASORS (2u * POWER_TABLE_OUTPUT)

/* The step's kernels are written once with loops over the blocks and
 * instantiated per layout size, where every loop unrolls (docs/design/filter.md,
 * "Instances per layout size"). */
#define KF_INLINE static inline __attribute__((always_inline))
#define KF_UNROLL _Pragma("GCC unroll 8")
/* The slow paths out of the way of the straight one. */
#define UNLIKELY(cond) __builtin_expect(!!(cond), 0)

typedef union {
    float f;
    uint32_t u;
} float_bits_t;

#define FLOAT_SIGN_BIT 0x80000000u
#define FLOAT_INF_BITS 0x7f800000u

static inline uint32_t bits_of(float x)
{
    const float_bits_t b = {.f = x};
    return b.u;
}

static inline bool is_nonneg(float x)
{
    return is_finite(x) && x >= 0.0f;
}

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

static inline unsigned packed_entries(unsigned nb)
{
    return tile_row_start(nb, nb) + 1u;
}

/* Packed position of P(i, j), i and j layout states (block slots, offset
 * at 2 nb). */
static inline unsigned packed_index(unsigned nb, unsigned i, unsigned j)
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

/* Zeroes n tiles of 4 from p (written tile by tile: GCC turns a plain
 * zeroing loop into a memset call, which the bare-metal boards provide
 * byte by byte). */
KF_INLINE void zero_tiles(float *p, unsigned n)
{
    for (; n > 0u; n--, p += 4) {
        p[0] = p[1] = p[2] = p[3] = 0.0f;
    }
}

/* Block s's states were written outside learning (cleared, restarted,
 * imported): a short event's rollback (hd_kf_gates.h) keeps them. */
KF_INLINE void keep_block_state(hd_kf_t *kf, unsigned s)
{
    kf->event_x[2u * s] = kf->x[2u * s];
    kf->event_x[2u * s + 1u] = kf->x[2u * s + 1u];
}

/* Block s starts again: state zero, its tile v I, zero covariance with
 * every other state (hd_kf.c). */
void hd_kf_clear_block(hd_kf_t *kf, unsigned s, float v);
/* motor_ref_inv from motor_ref (hd_kf.c). */
void hd_kf_follow_reference(hd_kf_t *kf);
/* The held output rows start again at 1, their regression empty (hd_kf.c). */
void hd_kf_follow_restart(hd_kf_t *kf);
/* With q_motion_ref_profiled_rad > 0: the blocks of `held` (by configured
 * index) take it as their motion reference, the others q_motion_ref_rad,
 * and the short plans' ranges follow; nothing when it is 0 (hd_kf.c). */
void hd_kf_profile_motion(hd_kf_t *kf, uint32_t held);

/* Phase lost: the blocks of `lost` restart from zero with their priors,
 * decorrelated, in one pass over P (hd_kf_bounds.c). */
void hd_kf_restart_lost_blocks(hd_kf_t *kf, uint32_t lost);

/* The bounds' slow path (hd_kf_bounds.c): the status bits raised. */
uint32_t hd_kf_bound_covariance(hd_kf_t *kf, float finite_probe);

/* hd_kf_rows.c.  |T_ref| of the load-dependent rows after this sample
 * (T_exp plus the real-torque offset, followed by the motor's motion
 * fraction, held at standstill; capped at HD_KF_MAX_ABS_Y_NM). */
float hd_kf_load_ref(hd_kf_t *kf, float torque_expected_nm, float d_motor_rad);
/* One step of the load the motor blocks learn at (hd_kf_t.learn_load_nm). */
void hd_kf_learn_load(hd_kf_t *kf, float torque_expected_nm);
/* The held output rows' next value into kf->output_row (output_follow):
 * the motor lines' growth since the profile import, read while `observed`,
 * else predicted from |T_ref|; HD_KF_STATUS_LOAD_BOUND where the target
 * is refused at the envelope, else 0. */
uint32_t hd_kf_follow_motor_lines(hd_kf_t *kf, float t_abs, bool observed);

#endif
