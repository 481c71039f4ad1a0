/* hd_calib_lsq: the least-squares fits and F-tests of the calibration
 * analysis (hd_calib.c).  Private to calib/. */
#ifndef HD_CALIB_LSQ_H
#define HD_CALIB_LSQ_H

#include <stdint.h>

#include "hd_calib.h"

#define LSQ_MAX_COLS 5u
#define PI_F 3.14159265f

static inline int finite_f(float f)
{
    return f == f && f <= 3.4028235e38f && f >= -3.4028235e38f;
}

static inline float abs_f(float f)
{
    return f < 0.0f ? -f : f;
}

/* Column-major design matrix for a small least-squares problem. */
typedef struct {
    uint32_t n, p;
    float x[LSQ_MAX_COLS][HD_CALIB_MAX_POINTS];
} design_t;

typedef struct {
    float beta[LSQ_MAX_COLS];
    float se[LSQ_MAX_COLS];   /* NaN if dropped or no residual degrees of freedom */
    uint8_t used[LSQ_MAX_COLS];
    uint32_t rank;
    float rss;
} lsq_t;

/* Modified Gram-Schmidt QR.  A column that is (numerically) a combination of
 * earlier ones is dropped instead of producing a meaningless coefficient
 * (e.g. the hysteresis column when only one branch was measured). */
void hd_calib_lsq_solve(const design_t *d, const float *y, lsq_t *out);

/* p-value of the F-test that the columns `full` has beyond `reduced`
 * improve the fit of n points (NaN when it cannot be judged). */
float hd_calib_nested_pvalue(const lsq_t *reduced, const lsq_t *full, uint32_t n);

#endif
