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

/* Below this |angle| hd_sincosf applies no reduction (quadrant 0) and
 * returns exactly hd_sin_poly / hd_cos_poly of the angle. */
#define HD_TRIG_NO_REDUCTION_RAD 0.78f

/* Taylor polynomials on [-pi/4, pi/4]: truncation error < 1e-9, far below
 * float32 rounding (6e-8).  Horner form, no division.  Inline, so the
 * filter's per-step sines of small increments cost no call. */
static inline float hd_sin_poly(float r)
{
    const float r2 = r * r;
    return r * (1.0f + r2 * (-1.0f / 6.0f + r2 * (1.0f / 120.0f
                + r2 * (-1.0f / 5040.0f + r2 * (1.0f / 362880.0f)))));
}

static inline float hd_cos_poly(float r)
{
    const float r2 = r * r;
    return 1.0f + r2 * (-0.5f + r2 * (1.0f / 24.0f + r2 * (-1.0f / 720.0f
                + r2 * (1.0f / 40320.0f + r2 * (-1.0f / 3628800.0f)))));
}

#ifdef __cplusplus
}
#endif

#endif /* HD_TRIG_H */
