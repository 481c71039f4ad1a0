/* hd_track: see hd_track.h. */
#include "hd_track.h"

#include "hd_float.h"

#define HD_TRACK_TWO_PI 6.28318530717958647692f
/* Above this w*ts the forward-Euler gains no longer place the poles where
 * the continuous design says (and the loop approaches instability). */
#define HD_TRACK_MAX_W_TS 0.5f

hd_kf_err_t hd_track_init(hd_track_t *t, float ts_s, float bandwidth_hz)
{
    if (!is_finite(ts_s) || ts_s <= 0.0f || !is_finite(bandwidth_hz) ||
        bandwidth_hz <= 0.0f) {
        return HD_KF_ERR_TRACK_BANDWIDTH;
    }
    const float w = HD_TRACK_TWO_PI * bandwidth_hz;
    if (w * ts_s > HD_TRACK_MAX_W_TS) {
        return HD_KF_ERR_TRACK_BANDWIDTH;
    }
    t->ts_s = ts_s;
    t->l1 = 3.0f * w * ts_s;
    t->l2 = 3.0f * w * w * ts_s;
    t->l3 = w * w * w * ts_s;
    t->err_rad = 0.0f;
    t->vel_rad_s = 0.0f;
    t->acc_rad_s2 = 0.0f;
    return HD_KF_OK;
}

hd_kf_err_t hd_track_update(hd_track_t *t, float d_angle_rad)
{
    const float ts = t->ts_s;
    /* Predict with the current velocity and acceleration. */
    float predicted = t->vel_rad_s * ts + 0.5f * t->acc_rad_s2 * ts * ts;
    t->vel_rad_s += t->acc_rad_s2 * ts;
    if (!is_finite(d_angle_rad)) {
        /* No measurement: assume the predicted motion happened. */
        return HD_KF_ERR_INPUT;
    }
    t->err_rad += d_angle_rad - predicted;
    /* Correct: theta_hat moves by l1 err, so the error shrinks by it. */
    const float e = t->err_rad;
    t->err_rad -= t->l1 * e;
    t->vel_rad_s += t->l2 * e;
    t->acc_rad_s2 += t->l3 * e;
    return HD_KF_OK;
}
