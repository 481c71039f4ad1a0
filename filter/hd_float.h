/* Float helpers the filter library shares without libm calls (internal to
 * filter/: not part of any public header). */
#ifndef HD_FLOAT_H
#define HD_FLOAT_H

#include <stdbool.h>

/* isfinite without a libm call: x - x is 0 only for finite x. */
static inline bool is_finite(float x)
{
    return (x - x) == 0.0f;
}

static inline float abs_f(float x)
{
    return x < 0.0f ? -x : x;
}

/* v / (|v| + eps): a sign function smoothed over eps > 0 (continuous). */
static inline float smooth_sign_f(float v, float eps)
{
    return v / (abs_f(v) + eps);
}

#endif /* HD_FLOAT_H */
