/* hd_ctrl_trig: cos and sin without libm for control/ (internal: hd_ctrl.c
 * and hd_artifact.c). */
#ifndef HD_CTRL_TRIG_H
#define HD_CTRL_TRIG_H

/* cos and sin by their Taylor series (Horner, to x^18 and x^19): |x| <= pi,
 * error < 2e-7; no libm in control/.  Term k divides by n (n - 1), n = 18,
 * 16, ..., 2 (cos) and 19, 17, ..., 3 (sin): multiplied by the reciprocal
 * instead (a division is 14 cycles on the M4F, in the tick when a notch
 * follows the speed). */
static const float COS_RECIP[9] = {1.0f / 306.0f, 1.0f / 240.0f, 1.0f / 182.0f, 1.0f / 132.0f,
                                   1.0f / 90.0f,  1.0f / 56.0f,  1.0f / 30.0f,  1.0f / 12.0f,
                                   1.0f / 2.0f};
static const float SIN_RECIP[9] = {1.0f / 342.0f, 1.0f / 272.0f, 1.0f / 210.0f, 1.0f / 156.0f,
                                   1.0f / 110.0f, 1.0f / 72.0f,  1.0f / 42.0f,  1.0f / 20.0f,
                                   1.0f / 6.0f};

static inline float cos_poly(float x)
{
    const float x2 = x * x;
    float r = 1.0f;
    for (unsigned k = 0; k < 9u; k++) {
        r = 1.0f - x2 * COS_RECIP[k] * r;
    }
    return r;
}

static inline float sin_poly(float x)
{
    const float x2 = x * x;
    float r = 1.0f;
    for (unsigned k = 0; k < 9u; k++) {
        r = 1.0f - x2 * SIN_RECIP[k] * r;
    }
    return x * r;
}

/* sin and cos of one angle |x| <= pi, for the tick (the narrowed
 * feedback's motor angle): reduced by quadrant to |r| <= pi / 4 (pi / 2 in
 * two parts, Cody-Waite), then Taylor polynomials of degree 9 and 10
 * (truncation < 1e-9); error < 3e-7.  About a third of cos_poly plus
 * sin_poly's work, and no loop. */
#define HD_CTRL_PIO2_HI 1.5703125f         /* pi / 2 to 8 bits: q * HI is exact */
#define HD_CTRL_PIO2_LO 4.83826794897e-4f  /* pi / 2 - HI */
static inline void sincos_quadrant(float x, float *s, float *c)
{
    const float t = x * 0.636619772f; /* 2 / pi */
    const int q = (int)(t + (t >= 0.0f ? 0.5f : -0.5f));
    const float r = (x - (float)q * HD_CTRL_PIO2_HI) - (float)q * HD_CTRL_PIO2_LO;
    const float r2 = r * r;
    const float sr = r * (1.0f + r2 * (-1.0f / 6.0f + r2 * (1.0f / 120.0f
                      + r2 * (-1.0f / 5040.0f + r2 * (1.0f / 362880.0f)))));
    const float cr = 1.0f + r2 * (-0.5f + r2 * (1.0f / 24.0f + r2 * (-1.0f / 720.0f
                      + r2 * (1.0f / 40320.0f + r2 * (-1.0f / 3628800.0f)))));
    switch ((unsigned)(q + 4) & 3u) { /* q in [-2, 2] */
    case 0u: *s = sr; *c = cr; break;
    case 1u: *s = cr; *c = -sr; break;
    case 2u: *s = -sr; *c = -cr; break;
    default: *s = -cr; *c = sr; break;
    }
}

#endif /* HD_CTRL_TRIG_H */
