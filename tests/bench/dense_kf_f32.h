/*
 * dense_kf_f32: a plain float32 textbook implementation of the filter of
 * filter/hd_kf.h, the peer of the compute benchmark: a correct filter
 * written the direct way, so the speed ratio compares two right answers.
 *
 * Every step it builds the full n x n transition Phi (this sample's
 * increments), the gain-fraction diagonal F, the measurement row C and Q,
 * and evaluates with dense matrix products (O(n^3)):
 *
 *   x <- Phi x,       P <- Phi P Phi' + Q            (time update)
 *   S = C P C' + R,   K = F P C' / S
 *   x <- x + K (y - C x)
 *   P <- (I - K C) P (I - K C)' + K R K'             (Joseph form: P stays
 *                                                      the covariance of the
 *                                                      estimate for any F;
 *                                                      expanded, O(n^2))
 *   P <- (P + P') / 2                                (symmetrisation)
 *
 * Same model features as hd_kf, from its header: lock kinds, motion-scaled
 * q and motor gains, output_learn_scale, the offset state with priming and
 * the jump gate, Nyquist freeze and phase loss, a p_max ceiling by
 * congruence (per diagonal entry, D_ii = sqrt(p_max / P_ii), where hd_kf
 * scales a block by its largest eigenvalue).  Not the load-dependent row:
 * ripple_load_coeff_per_nm must be 0 (the benchmark's models).  Agreement with the double reference is
 * printed by the benchmark.
 *
 * Firmware-compatible C (no heap, no VLAs, no libm: sine/cosine from
 * filter/hd_trig.h, sqrtf is VSQRT) so the same file is cross-compiled for
 * the Cortex-M4 instruction count.
 */
#ifndef DENSE_KF_F32_H
#define DENSE_KF_F32_H

#include "hd_kf.h"

#define DENSE_KF_MAX_N HD_KF_MAX_STATES

typedef struct {
    hd_kf_config_t cfg;
    int n;                                   /* active states */
    int nb;                                  /* active blocks */
    int block_of_slot[HD_KF_MAX_BLOCKS];     /* active slot -> configured block */
    int offset_slot;                         /* -1: no offset state */
    int offset_primed;
    float x[DENSE_KF_MAX_N];
    float p[DENSE_KF_MAX_N][DENSE_KF_MAX_N];
} dense_kf_f32_t;

typedef struct {
    float torque_filtered_nm;
    float ripple_nm;
    float innovation_nm;
} dense_kf_f32_output_t;

/* Copies cfg (validate it with hd_kf_config_check first), x = 0, P = p0 I. */
void dense_kf_f32_init(dense_kf_f32_t *kf, const hd_kf_config_t *cfg);

/* One step with full dense matrices. */
void dense_kf_f32_step(dense_kf_f32_t *kf, const hd_kf_input_t *in,
                       dense_kf_f32_output_t *out);

#endif /* DENSE_KF_F32_H */
