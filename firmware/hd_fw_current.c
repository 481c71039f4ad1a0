/* hd_fw_current: the current estimator stage (hd_fw_stages.h).
 *
 * Contract: hd_fw_current once per tick after the encoders reads the
 * optional motor-current channel into the sample (NaN without a channel).
 * A failed or non-finite reading holds the last good value; it is a fault
 * (HD_FAULT_CURRENT_ERROR) only when T_exp uses the current.  The
 * estimator's low-pass state (est) is advanced by the filter stage, inside
 * hd_pipeline_sample (filter/hd_slow.h), so the replay runs the same code;
 * it lives here because it outlives a model rebuild. */
#include <math.h> /* NAN: a constant, no libm call */
#include <string.h>

#include "hd_fw.h"
#include "hd_fw_internal.h"

uint32_t hd_fw_current(hd_fw_current_t *k, const hd_fw_config_t *c, const hal_sensors_t *sen,
                       hd_fw_sample_t *s)
{
    s->motor_current_a = NAN;
    if (sen->current_read == NULL) {
        return 0u;
    }
    hal_current_sample_t cur;
    memset(&cur, 0, sizeof cur);
    const int rc = sen->current_read(sen->ctx, &cur);
    const bool good = rc == HAL_OK && !cur.fault && isfinite(cur.motor_current_a);
    if (good) {
        k->current_a = cur.motor_current_a;
    }
    s->motor_current_a = k->current_a;
    return (!good && c->current.nm_per_a > 0.0f) ? HD_FAULT_CURRENT_ERROR : 0u;
}
