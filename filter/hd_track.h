/*
 * hd_track: angle -> velocity -> acceleration tracking loop (allocation-free).
 *
 * A third-order tracking observer driven by measured angle increments.  It
 * never stores an absolute angle in float32 (which would lose resolution after
 * a few thousand revolutions); it keeps only the tracking error
 * err = theta_meas - theta_hat, advanced by increments:
 *
 *   err += d_theta_meas - (vel * ts + acc * ts^2 / 2)        (predict)
 *   vel += acc * ts
 *   theta_hat += l1 err, vel += l2 err, acc += l3 err         (correct)
 *
 * Gains place all three observer poles at s = -w, w = 2 pi bandwidth_hz
 * (critically damped): l1 = 3 w ts, l2 = 3 w^2 ts, l3 = w^3 ts.  The velocity
 * estimate follows a velocity step with ~1/bandwidth settling and no steady
 * error on ramps; acceleration noise grows with bandwidth^2.  Default 20 Hz.
 */
#ifndef HD_TRACK_H
#define HD_TRACK_H

#include "hd_filter_err.h"

#ifdef __cplusplus
extern "C" {
#endif

#define HD_TRACK_DEFAULT_BANDWIDTH_HZ 20.0f

typedef struct {
    float ts_s;
    float l1, l2, l3;      /* observer gains (see above) */
    float err_rad;         /* theta_meas - theta_hat */
    float vel_rad_s;
    float acc_rad_s2;
} hd_track_t;

/* Returns HD_KF_OK, or HD_KF_ERR_TRACK_BANDWIDTH if ts_s or bandwidth is
 * not finite and positive or the bandwidth is too high for the sample rate
 * (w ts > 0.5). */
hd_kf_err_t hd_track_init(hd_track_t *t, float ts_s, float bandwidth_hz);

/* Feeds the measured angle increment since the previous call.  A non-finite
 * increment is ignored (prediction only) and returns HD_KF_ERR_INPUT. */
hd_kf_err_t hd_track_update(hd_track_t *t, float d_angle_rad);

#ifdef __cplusplus
}
#endif

#endif /* HD_TRACK_H */
