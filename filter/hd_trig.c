#include "hd_trig.h"

/* pi/2 split for Cody-Waite reduction: HALF_PI_HI has few significant bits,
 * so q * HALF_PI_HI is exact for |q| < 2^16 and the reduction keeps full
 * float precision for |angle| up to ~1e5 rad. */
#define HALF_PI_HI 1.5703125f
#define HALF_PI_LO 4.83826794897e-4f
#define TWO_OVER_PI 0.636619772367581f
#define MAX_REDUCIBLE_RAD 1.0e5f
/* Below this |angle| the quadrant is 0 (angle * 2 / pi < 0.4966) and the
 * reduction leaves the angle as it is: skip it. */
#define NO_REDUCTION_RAD 0.78f

/* Taylor polynomials on [-pi/4, pi/4]: truncation error < 1e-9, far below
 * float32 rounding (6e-8). Horner form, no division. */
static float sin_poly(float r)
{
    const float r2 = r * r;
    return r * (1.0f + r2 * (-1.0f / 6.0f + r2 * (1.0f / 120.0f
                + r2 * (-1.0f / 5040.0f + r2 * (1.0f / 362880.0f)))));
}

static float cos_poly(float r)
{
    const float r2 = r * r;
    return 1.0f + r2 * (-0.5f + r2 * (1.0f / 24.0f + r2 * (-1.0f / 720.0f
                + r2 * (1.0f / 40320.0f + r2 * (-1.0f / 3628800.0f)))));
}

void hd_sincosf(float angle_rad, float *sin_out, float *cos_out)
{
    /* Non-finite or absurdly large angles: return the zero rotation rather
     * than garbage; callers flag such inputs before they get here. */
    if (!(angle_rad <= MAX_REDUCIBLE_RAD && angle_rad >= -MAX_REDUCIBLE_RAD)) {
        *sin_out = 0.0f;
        *cos_out = 1.0f;
        return;
    }
    if (angle_rad < NO_REDUCTION_RAD && angle_rad > -NO_REDUCTION_RAD) {
        /* quadrant 0: the same bits as the reduction below gives */
        *sin_out = sin_poly(angle_rad);
        *cos_out = cos_poly(angle_rad);
        return;
    }
    const float scaled = angle_rad * TWO_OVER_PI;
    const int quadrant = (int)(scaled + (scaled >= 0.0f ? 0.5f : -0.5f));
    const float qf = (float)quadrant;
    const float r = (angle_rad - qf * HALF_PI_HI) - qf * HALF_PI_LO;
    const float s = sin_poly(r);
    const float c = cos_poly(r);
    switch ((unsigned)quadrant & 3u) {
    case 0u: *sin_out = s; *cos_out = c; break;
    case 1u: *sin_out = c; *cos_out = -s; break;
    case 2u: *sin_out = -s; *cos_out = -c; break;
    default: *sin_out = -c; *cos_out = s; break;
    }
}
