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

/* A short event (hd_kf.h, HD_KF_EVENT_TURN_RAD): the blocks' states are
 * kept at its first step; it covers the motor angles since then and its
 * largest innovation. */
KF_INLINE void event_begin(hd_kf_t *kf, float e2)
{
    kf->event_angle_rad = kf->event_min_rad = kf->event_max_rad = 0.0f;
    kf->event_peak_nm2 = e2;
    for (unsigned i = 0; i < 2u * kf->n_blocks; i++) {
        kf->event_x[i] = kf->x[i];
    }
}

KF_INLINE void event_cover(hd_kf_t *kf, float e2, float d_motor_rad)
{
    const float a = kf->event_angle_rad + d_motor_rad;
    kf->event_angle_rad = a;
    kf->event_min_rad = a < kf->event_min_rad ? a : kf->event_min_rad;
    kf->event_max_rad = a > kf->event_max_rad ? a : kf->event_max_rad;
    kf->event_peak_nm2 = e2 > kf->event_peak_nm2 ? e2 : kf->event_peak_nm2;
}

/* At the event's end: an innovation beyond any modelled line
 * (correction_max_nm) over less than a motor turn cannot have taught the
 * blocks a line, only the transient's torque as it fell on their phases. */
KF_INLINE bool event_was_transient(const hd_kf_t *kf)
{
    const float lim = kf->cfg.correction_max_nm;
    return lim > 0.0f && kf->event_peak_nm2 > lim * lim &&
           kf->event_max_rad - kf->event_min_rad < HD_KF_EVENT_TURN_RAD;
}

/* The correction limit's restart within an event over less than a motor
 * turn: the states at its start are the restart, and the event ends here
 * (the gate re-armed).  Returns whether it did. */
KF_INLINE bool event_restores(hd_kf_t *kf)
{
    if (kf->jump_hold_steps == 0u ||
        !(kf->event_max_rad - kf->event_min_rad < HD_KF_EVENT_TURN_RAD)) {
        return false;
    }
    kf->jump_hold_steps = 0u;
    kf->jump_credit = HD_KF_JUMP_BURST;
    return true;
}

/* Offset-jump gate: e beyond offset_jump_nm and 4 sigma, at most
 * HD_KF_JUMP_BURST jumps per event: each step beyond the gate restarts
 * the quiet count, and the jumps come back once jump_rearm_steps steps in
 * a row stayed within it; a step beyond it with none left is counted.
 * *rollback is set at the end of a transient event.
 * Returns HD_KF_STATUS_OFFSET_JUMP, HD_KF_STATUS_UNMODELLED or 0. */
KF_INLINE uint32_t offset_jump(hd_kf_t *kf, float e, float s_var, float d_motor_rad,
                               bool *rollback)
{
    const float jump_nm = kf->cfg.offset_jump_nm;
    const float e2 = e * e;
    const bool beyond = kf->cfg.offset_enabled && jump_nm > 0.0f && e2 > jump_nm * jump_nm &&
                        e2 > JUMP_MIN_SIGMA * JUMP_MIN_SIGMA * s_var;
    if (kf->jump_hold_steps > 0u) {
        event_cover(kf, e2, d_motor_rad);
    }
    if (!beyond) {
        if (kf->jump_hold_steps > 0u && --kf->jump_hold_steps == 0u) {
            kf->jump_credit = HD_KF_JUMP_BURST;
            *rollback = event_was_transient(kf);
        }
        return 0u;
    }
    if (kf->jump_hold_steps == 0u) {
        event_begin(kf, e2);
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
