/*
 * Sine and cosine without libm, for the 1 kHz path.
 *
 * hd_sincosf: range-reduced to [-pi/4, pi/4] by quadrant (Cody-Waite, two
 * constants), then Taylor polynomials of degree 9 (sine) and 10 (cosine),
 * whose truncation error (< 1e-9) is far below float32 rounding.  Max abs
 * error < 2e-7 on [-pi, pi] and < 1e-6 for |angle| up to 1e4 rad.  Non-finite
 * or |angle| > 1e5 rad returns sin 0, cos 1.  Bounded time: no loops, no
 * table, no division.  Pure: same bits on every IEEE-754 float32 target when
 * built with -ffp-contract=off.
 */
#ifndef HD_TRIG_H
#define HD_TRIG_H

#ifdef __cplusplus
extern "C" {
#endif

#define HD_PI_F 3.14159265358979323846f
#define HD_TWO_PI_F 6.28318530717958647692f

void hd_sincosf(float angle_rad, float *sin_out, float *cos_out);

#ifdef __cplusplus
}
#endif

#endif /* HD_TRIG_H */
