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

#endif /* HD_FLOAT_H */
