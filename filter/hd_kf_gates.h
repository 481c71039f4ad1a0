/* hd_kf_gates: the step's gates on the innovation and on what it
 * publishes (hd_kf.h: offset jumps, offset drift, the correction limit).
 * Internal to hd_kf_step.c, the only file that includes it: the step is one
 * translation unit, so these inline into it as before. */
#ifndef HD_KF_GATES_H
#define HD_KF_GATES_H

#include <stdbool.h>
#include <stdint.h>

#include "hd_kf_internal.h"

#define JUMP_MIN_SIGMA 4.0f

/* Offset-jump gate: e beyond offset_jump_nm and 4 sigma, at most
 * HD_KF_JUMP_BURST jumps per event: each step beyond the gate restarts
 * the quiet count, and the jumps come back once jump_rearm_steps steps in
 * a row stayed within it; a step beyond it with none left is counted.
 * Returns HD_KF_STATUS_OFFSET_JUMP, HD_KF_STATUS_UNMODELLED or 0. */
KF_INLINE uint32_t offset_jump(hd_kf_t *kf, float e, float s_var)
{
    const float jump_nm = kf->cfg.offset_jump_nm;
    const float e2 = e * e;
    const bool beyond = kf->cfg.offset_enabled && jump_nm > 0.0f && e2 > jump_nm * jump_nm &&
                        e2 > JUMP_MIN_SIGMA * JUMP_MIN_SIGMA * s_var;
    if (!beyond) {
        if (kf->jump_hold_steps > 0u && --kf->jump_hold_steps == 0u) {
            kf->jump_credit = HD_KF_JUMP_BURST;
        }
        return 0u;
    }
    kf->jump_hold_steps = kf->jump_rearm_steps;
    if (kf->jump_credit == 0u) {
        kf->jump_held_count++;
        return HD_KF_STATUS_UNMODELLED;
    }
    kf->jump_credit--;
    return HD_KF_STATUS_OFFSET_JUMP;
}

/* Offset drift gate (hd_kf.h): while the hold the jump gate (re)starts
 * lasts, the offset's q is offset_drift_q_nm2.  Returns the step's q. */
KF_INLINE float offset_drift(hd_kf_t *kf, float q_off)
{
    if (kf->drift_hold_steps == 0u) {
        return q_off;
    }
    kf->drift_hold_steps--;
    kf->drift_count++;
    return kf->cfg.offset_drift_q_nm2;
}

/* The correction limit: a correction beyond +-correction_max_nm is wrong
 * (no modelled line is that large), so the step publishes the measurement
 * itself, never worse than raw (ripple_nm then carries the published
 * correction, 0).
 * limit_steps counts up at the limit and down below it (a wrong estimate
 * oscillates, crossing zero twice a cycle): once the steps at the limit
 * outnumber the others by limit_restart_steps, the filter restarts after
 * the step.  A non-finite correction is left to the final check. */
static uint32_t limit_correction(hd_kf_t *kf, float meas_nm, float correction,
                                 hd_kf_output_t *out, float *filtered, bool *restart)
{
    const float lim = kf->cfg.correction_max_nm;
    if (!(correction > lim || correction < -lim)) {
        kf->limit_steps -= kf->limit_steps > 0u ? 1u : 0u;
        return 0u;
    }
    *filtered = meas_nm;
    out->ripple_nm = -(kf->cfg.offset_is_sensor_error ? out->offset_nm : 0.0f);
    kf->limit_count++;
    if (++kf->limit_steps >= kf->limit_restart_steps) {
        kf->limit_steps = 0u;
        *restart = true;
    }
    return HD_KF_STATUS_LIMITED;
}

#endif /* HD_KF_GATES_H */
