/*
 * dense_kf_f32: a textbook Kalman filter in float32 with dense matrices, the
 * baseline the project's structured filter (filter/hd_kf.c) is compared
 * against for compute cost (issue 7).  Same model as hd_kf (a bank of
 * rotation blocks plus an optional offset, C = [1 0 1 0 ... (1)]), but
 * written the way a textbook states the prediction-type filter, with
 * general n x n matrix products and no use of the structure:
 *
 *   Phi  (rebuilt every step from the angle increments)
 *   e = y - C x,  S = C P C' + R,  K = Phi P C' / S
 *   x <- Phi x + K e
 *   P <- Phi P Phi' + Q - K S K'
 *
 * Cost O(n^3) per step.  No heap, fixed capacity DENSE_KF_MAX_STATES.
 * It is only a benchmark reference: no Nyquist freezing, clamping or fault
 * handling.
 */
#ifndef DENSE_KF_F32_H
#define DENSE_KF_F32_H

#include <stdint.h>

#ifdef __cplusplus
extern "C" {
#endif

#define DENSE_KF_MAX_STATES 17
#define DENSE_KF_MAX_BLOCKS 8

typedef struct {
    unsigned n;                 /* states */
    unsigned blocks;            /* rotation blocks; n = 2 blocks (+1 offset) */
    float order[DENSE_KF_MAX_BLOCKS]; /* phase advance = order * d_angle */
    float x[DENSE_KF_MAX_STATES];
    float p[DENSE_KF_MAX_STATES][DENSE_KF_MAX_STATES];
    float q[DENSE_KF_MAX_STATES][DENSE_KF_MAX_STATES];
    float phi[DENSE_KF_MAX_STATES][DENSE_KF_MAX_STATES];
    float c[DENSE_KF_MAX_STATES];
    float r;
} dense_kf_t;

/* blocks <= DENSE_KF_MAX_BLOCKS, offset 0/1; Q = q I, P = p0 I.
 * Returns 0, or -1 if the size is out of range. */
int dense_kf_init(dense_kf_t *kf, unsigned blocks, const float *orders, int offset,
                  float q, float r, float p0);

/* One step with measurement y (ripple) and the angle increment d_angle;
 * returns the predicted ripple C x before the update. */
float dense_kf_step(dense_kf_t *kf, float y, float d_angle_rad);

#ifdef __cplusplus
}
#endif

#endif /* DENSE_KF_F32_H */
