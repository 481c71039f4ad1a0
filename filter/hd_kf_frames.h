/* hd_kf_frames: the arithmetic of the frames' turn (sines and cosines of a
 * step, the exactly accumulated phase, phasor products and powers), inline
 * in the step (hd_kf_step.c).  Private to filter/. */
#ifndef HD_KF_FRAMES_H
#define HD_KF_FRAMES_H

#include <math.h>

#include "hd_kf_internal.h"
#include "hd_trig.h"

/* Below this |angle| [rad] sine and cosine come from their series
 * a - a^3/6 and 1 - a^2/2 + a^4/24: the next terms are < 1e-8 relative,
 * under float32 rounding. */
#define SMALL_ANGLE_RAD 0.03125f

/* Steps the output phasor turns by increments before it is set again from
 * the exactly accumulated output phase. */
#define OUTPUT_TURNS_MAX 256u

/* 2 pi as hi + lo: hi has 16 significant bits, so hi's multiples and
 * differences near pi are exact. */
#define TWO_PI_HI 6.28125f
#define TWO_PI_LO 1.9353071795864769e-3f

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

#endif
