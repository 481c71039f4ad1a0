/*
 * dense_kf_f32: a deliberately plain float32 "textbook" implementation of
 * the paper's prediction-type Kalman filter (Taghirad, Helmy & Belanger
 * 1997, equations 8-10), used only as the peer in the compute benchmark.
 *
 * It builds the full n x n transition matrix Phi every step and evaluates
 * the equations literally with dense matrix products, O(n^3) per step:
 *
 *   S   = C P C' + R                      (scalar: one torque measurement)
 *   K   = Phi P C' / S                    (9)
 *   x  <- Phi x + K (y - C x)             (8)
 *   P  <- (Phi - K C) P Phi' + Q          (10)
 *
 * Same model as filter/hd_kf.h (blocks locked to motor / output / fixed
 * references, optional random-walk offset state, outputs from the prior),
 * but none of hd_kf's engineering: no symmetry enforcement, no covariance
 * ceiling, no Nyquist freeze, no fault handling.  It is what a direct
 * transcription of the paper costs, so the benchmark can show what the
 * block-diagonal O(n^2) update buys.
 *
 * Firmware-compatible C (no heap, no VLAs, no libm: sine/cosine from
 * filter/hd_trig.h) so the same file can be cross-compiled for the
 * Cortex-M4 instruction count.
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

/* One step of equations 8-10 with full dense matrices. */
void dense_kf_f32_step(dense_kf_f32_t *kf, const hd_kf_input_t *in,
                       dense_kf_f32_output_t *out);

#endif /* DENSE_KF_F32_H */
