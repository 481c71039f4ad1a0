/*
 * hd_artifact: a narrowband copy of the filter's artifact estimate, locked
 * to the motor angle (the torque loop's HD_CTRL_FB_NARROW feedback).
 *
 * Pure: no I/O, no heap, no libm; float32, bounded time.  Given each tick
 * the filter's artifact estimate a (the raw torque minus the filtered one)
 * and the motor angle theta, it keeps one phasor z_k per motor order k of
 * its mask and one slow term z_0, and estimates
 *
 *   a_hat = z_0 + sum_k Re(z_k e^{j k theta})
 *
 * from the phasors before this tick's update (a prediction: a_hat does not
 * depend on this tick's a).  The update on the residual e = a - a_hat:
 *
 *   z_k += 2 w ts m e e^{-j k theta},   z_0 += w ts m e,   w = 2 pi corner_hz,
 *
 * m in [0, 1] the caller's weight (0 holds the phasors: the motor barely
 * turns and cos and sin of k theta cannot be told apart).  On the average
 * over a line's period each phasor follows its line's complex amplitude
 * through a first-order low-pass of corner w (Bodson's adaptive feedforward
 * cancellation): a line locked to the angle is removed fully, a change of
 * its amplitude or phase only after about 1 / w, and at constant speed the
 * residual e is a carries through notches at the lines (and at 0 for z_0),
 * each 2 corner_hz wide at -3 dB, unity gain away from them.  Locked to the
 * angle, not to the speed: a phasor learned before a reversal holds after
 * it.
 */
#ifndef HD_ARTIFACT_H
#define HD_ARTIFACT_H

#include <stdint.h>

#ifdef __cplusplus
extern "C" {
#endif

#define HD_ARTIFACT_ORDER_MAX 8u /* mask bit k-1: motor order k, k = 1..8 */

typedef struct {
    uint8_t mask;        /* bit k-1: a phasor at motor order k */
    uint8_t top;         /* the highest order in mask (0: none) */
    float gain;          /* w ts */
    float re[HD_ARTIFACT_ORDER_MAX + 1u]; /* [0]: the slow term z_0; [k]: Re z_k */
    float im[HD_ARTIFACT_ORDER_MAX + 1u]; /* [k]: Im z_k ([0] unused) */
} hd_artifact_t;

/* corner_hz > 0, ts_s > 0 (the caller checks); the phasors start at 0. */
void hd_artifact_init(hd_artifact_t *t, uint8_t mask, float corner_hz, float ts_s);

/* A new mask, keeping the phasors of orders in both masks: those of orders
 * that leave are cleared (an order that enters again starts at 0). */
void hd_artifact_remask(hd_artifact_t *t, uint8_t mask);

/* The phasors back to 0. */
void hd_artifact_reset(hd_artifact_t *t);

/* One tick: returns a_hat at motor_angle_rad (any finite angle; wrapped
 * here), then updates the phasors with weight m (clamped to [0, 1]) on the
 * residual a_nm - a_hat.  A non-finite a_nm or angle updates nothing (and a
 * non-finite angle returns z_0). */
float hd_artifact_step(hd_artifact_t *t, float a_nm, float motor_angle_rad, float m);

#ifdef __cplusplus
}
#endif

#endif /* HD_ARTIFACT_H */
