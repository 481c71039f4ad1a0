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

#endif /* HD_CTRL_TRIG_H */
