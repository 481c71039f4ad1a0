#include "hd_trig.h"

/* pi/2 split for Cody-Waite reduction: HALF_PI_HI has few significant bits,
 * so q * HALF_PI_HI is exact for |q| < 2^16 and the reduction keeps full
 * float precision for |angle| up to ~1e5 rad. */
#define HALF_PI_HI 1.5703125f
#define HALF_PI_LO 4.83826794897e-4f
#define TWO_OVER_PI 0.636619772367581f
#define MAX_REDUCIBLE_RAD 1.0e5f

void hd_sincosf(float angle_rad, float *sin_out, float *cos_out)
{
    /* Non-finite or absurdly large angles: return the zero rotation rather
     * than garbage; callers flag such inputs before they get here. */
    if (!(angle_rad <= MAX_REDUCIBLE_RAD && angle_rad >= -MAX_REDUCIBLE_RAD)) {
        *sin_out = 0.0f;
        *cos_out = 1.0f;
        return;
    }
    if (angle_rad < HD_TRIG_NO_REDUCTION_RAD && angle_rad > -HD_TRIG_NO_REDUCTION_RAD) {
        /* quadrant 0 (angle * 2 / pi < 0.4966): the reduction would leave
         * the angle as it is */
        *sin_out = hd_sin_poly(angle_rad);
        *cos_out = hd_cos_poly(angle_rad);
        return;
    }
    const float scaled = angle_rad * TWO_OVER_PI;
    const int quadrant = (int)(scaled + (scaled >= 0.0f ? 0.5f : -0.5f));
    const float qf = (float)quadrant;
    const float r = (angle_rad - qf * HALF_PI_HI) - qf * HALF_PI_LO;
    const float s = hd_sin_poly(r);
    const float c = hd_cos_poly(r);
    switch ((unsigned)quadrant & 3u) {
    case 0u: *sin_out = s; *cos_out = c; break;
    case 1u: *sin_out = c; *cos_out = -s; break;
    case 2u: *sin_out = -s; *cos_out = -c; break;
    default: *sin_out = -c; *cos_out = s; break;
    }
}
