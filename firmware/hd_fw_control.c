/* hd_fw_control: the tick's control stage (issue 23), after the pipeline.
 *
 *   setpoint (SETPOINT / GAINS frames, checked on receipt: a refused one
 *   never reaches the law) -> safe mode (watchdog, fault reactions) -> the
 *   law (control/hd_ctrl: modes, torque loop, limits applied last) -> drive.
 *
 * Fault reactions (docs/design/firmware.md, "Control"):
 *   no new setpoint for ctrl_watchdog_ms      DAMP, then STOP after ctrl_damp_ms
 *   motor encoder lost (ENC_FAULT)            STOP, latched until a STOP setpoint
 *   drive fault or a failed drive call        STOP, latched until a STOP setpoint
 *   gauge unusable (ADC error, saturated,     the torque loop cannot run: DAMP
 *     open bridge, beyond range), filter reset   (hd_ctrl's fallback)
 *   filter frozen                             none: the frozen block holds its
 *                                             estimate, the output stays usable
 *   bus-off, repeated deadline misses         DAMP while they last (bus-off: until
 *                                             a send period passes without one)
 *   a bad setpoint                            refused (ACK + fault), the last
 *                                             good one stays and ages
 * Without a drive (hal.actuator absent) the stage does nothing at all: the
 * firmware sends and computes what it did before control existed. */
#include <math.h> /* isfinite: a compiler builtin, no libm call */

#include "hd_fw.h"
#include "hd_fw_internal.h"

#define SENSOR_FAULTS \
    (HD_FAULT_ADC_ERROR | HD_FAULT_ADC_SATURATED | HD_FAULT_OPEN_BRIDGE | HD_FAULT_TORQUE_RANGE)

/* ------------------------------------------------------------- receive */

/* One ACK per tick goes out (publish); the fault bit marks every refusal. */
static void refuse(hd_fw_t *fw, uint8_t token, uint8_t aux, int result)
{
    hd_fw_ctrl_state_t *c = &fw->control;
    c->refuse_pending = true;
    c->refuse_node = hd_fw_live(fw)->cfg.node_id;
    c->refuse_token = token;
    c->refuse_aux = aux;
    c->refuse_result = (uint8_t)result;
    fw->tick.pending_faults |= HD_FAULT_SETPOINT_REFUSED;
}

static bool within(float x, float lo, float hi)
{
    return x >= lo && x <= hi;
}

static int check_setpoint(const hd_fw_t *fw, const hd_can_setpoint_t *in, hd_ctrl_setpoint_t *out)
{
    const hd_ctrl_config_t *k = &hd_fw_live(fw)->ctrl.cfg;
    if (in->mode >= (uint8_t)HD_CTRL_MODE_COUNT) {
        return HD_CAN_RES_OUT_OF_RANGE;
    }
    if (in->mode != (uint8_t)HD_CTRL_STOP && !hd_fw_has_drive(fw)) {
        return HD_CAN_RES_UNSUPPORTED;
    }
    if (!within(in->torque_nm, -k->torque_limit_nm, k->torque_limit_nm) ||
        (in->mode == (uint8_t)HD_CTRL_IMPEDANCE &&
         !within(in->position_rad, k->position_min_rad, k->position_max_rad))) {
        return HD_CAN_RES_OUT_OF_RANGE;
    }
    *out = (hd_ctrl_setpoint_t){(hd_ctrl_mode_t)in->mode, in->torque_nm, in->position_rad,
                                in->velocity_rad_s, 0.0f, 0.0f};
    return HD_CAN_RES_OK;
}

static void take_gains(hd_fw_t *fw, const hal_can_frame_t *f)
{
    hd_can_gains_t g;
    int rc = hd_can_decode_gains(f, &g);
    if (rc == HD_CAN_RES_OK && (!within(g.kp_nm_rad, 0.0f, HD_CTRL_KP_MAX_NM_RAD) ||
                                !within(g.kd_nm_s_rad, 0.0f, HD_CTRL_KD_MAX_NM_S_RAD))) {
        rc = HD_CAN_RES_OUT_OF_RANGE;
    }
    if (rc != HD_CAN_RES_OK) {
        refuse(fw, 0u, 1u, rc);
        return;
    }
    fw->control.kp_nm_rad = g.kp_nm_rad;
    fw->control.kd_nm_s_rad = g.kd_nm_s_rad;
}

void hd_fw_take_control_frame(hd_fw_t *fw, const hal_can_frame_t *f, uint8_t type)
{
    if (type == (uint8_t)HD_CAN_FRAME_GAINS) {
        take_gains(fw, f);
        return;
    }
    hd_fw_ctrl_state_t *c = &fw->control;
    hd_can_setpoint_t sp; /* the decode assigns every field; seq is the ACK's before it */
    sp.seq = 0u;
    hd_ctrl_setpoint_t next;
    int rc = hd_can_decode_setpoint(f, &sp);
    if (rc == HD_CAN_RES_OK) {
        rc = check_setpoint(fw, &sp, &next);
    }
    if (rc != HD_CAN_RES_OK) {
        refuse(fw, sp.seq, 0u, rc);
        return;
    }
    if (c->sp_have && sp.seq == c->sp_seq) {
        return; /* a repeat is stale, not new: it does not feed the watchdog */
    }
    c->sp = next;
    c->sp_have = true;
    c->sp_seq = sp.seq;
    c->sp_age_ticks = 0u;
    c->watchdog = false;
    if (next.mode == HD_CTRL_STOP) {
        c->stop_latched = false; /* STOP re-arms after a latched fault */
    }
}

/* --------------------------------------------------------------- stage */

/* The output angle since boot: a compensated (Kahan) sum of the output
 * encoder's increments the filter used (so that 1 mrad steps still add up
 * at 30 rad), plus where in the encoder's count the output is.  A count
 * says only that the angle lies in [count, count + 1) (a truncating
 * encoder: the count is its cell's lower edge); the motor's increments
 * over the gear ratio, N times finer, say where, up to the flexspline's
 * windup since the last count edge.  Without them a 4096-count output
 * encoder holds a 500 N m/rad impedance's 20 mrad deflection to a count,
 * 1.5 mrad: most of the rendered stiffness's error (docs/results/control.md). */
static void track_angle(hd_fw_ctrl_state_t *c, const hd_fw_sample_t *s,
                        const hd_fw_settings_t *set)
{
    const float d_rad = s->d_output_angle_rad;
    const float y = d_rad - c->angle_comp_rad;
    const float t = c->angle_rad + y;
    c->angle_comp_rad = (t - c->angle_rad) - y;
    c->angle_rad = t;
    if (s->has_output) {
        const float cell = set->output_rad_per_count;
        const float f = c->angle_fine_rad + s->d_motor_angle_rad / set->cfg.gear_ratio - d_rad;
        c->angle_fine_rad = f < 0.0f ? 0.0f : (f > cell ? cell : f);
    }
}

static void score_deadline_misses(hd_fw_t *fw)
{
    hd_fw_ctrl_state_t *c = &fw->control;
    const uint32_t missed = fw->counters.deadline_misses - c->misses_seen;
    c->misses_seen = fw->counters.deadline_misses;
    const uint32_t add = missed > 1000u ? 10000u : missed * HD_FW_MISS_WEIGHT;
    uint32_t score = c->miss_score + add; /* both <= 10000: no wrap */
    if (score > 10000u) {
        score = 10000u;
    }
    c->miss_score = score > 0u ? score - 1u : 0u;
}

/* The drive's own report: a fault latches STOP. */
static uint32_t drive_status(hd_fw_t *fw)
{
    const hal_actuator_t *a = &fw->hal->actuator;
    hal_drive_status_t st;
    if (a->status == NULL || a->status(a->ctx, &st) != HAL_OK || !st.fault) {
        return 0u;
    }
    fw->control.stop_latched = true;
    return HD_FAULT_DRIVE_FAULT;
}

/* The mode the inputs allow: the watchdog and the fault reactions above. */
static hd_ctrl_mode_t safe_mode(hd_fw_t *fw, uint32_t faults, uint32_t *raised)
{
    hd_fw_ctrl_state_t *c = &fw->control;
    const hd_fw_config_t *k = &hd_fw_live(fw)->cfg;
    hd_ctrl_mode_t m = c->sp.mode;
    if (m != HD_CTRL_STOP && c->sp_age_ticks >= k->ctrl_watchdog_ms) {
        c->watchdog = true;
        *raised |= HD_FAULT_CTRL_WATCHDOG;
        m = c->sp_age_ticks >= (uint32_t)k->ctrl_watchdog_ms + k->ctrl_damp_ms ? HD_CTRL_STOP
                                                                              : HD_CTRL_DAMP;
    }
    if ((faults & HD_FAULT_ENC_FAULT) != 0u) {
        c->stop_latched = true;
    }
    /* A bus-off is seen only when a send fails, and sends come once per
     * telemetry period (or heartbeat): DAMP holds until a period passes
     * without one, else it would flicker with the sends. */
    if ((faults & HD_FAULT_CAN_BUS_OFF) != 0u) {
        const uint32_t period = hd_fw_live(fw)->telem_divider;
        c->bus_off_hold_ticks = period > 0u ? period : HD_FW_HEARTBEAT_TICKS;
    }
    const bool damp = c->bus_off_hold_ticks > 0u || c->miss_score >= HD_FW_MISS_DAMP_SCORE;
    if (c->bus_off_hold_ticks > 0u) {
        c->bus_off_hold_ticks--;
    }
    hd_ctrl_mode_t safe = m;
    if (c->stop_latched) {
        safe = HD_CTRL_STOP;
    } else if (damp && m != HD_CTRL_STOP) {
        safe = HD_CTRL_DAMP;
    }
    if (safe != m) {
        *raised |= HD_FAULT_CTRL_FALLBACK;
    }
    return safe;
}

/* Tells the drive; a failed call is a drive fault (STOP, latched). */
static uint32_t command_drive(hd_fw_t *fw, const hd_ctrl_output_t *o)
{
    hd_fw_ctrl_state_t *c = &fw->control;
    const hal_actuator_t *a = &fw->hal->actuator;
    int rc = HAL_OK;
    if (o->enable != c->drive_on) {
        rc = a->enable(a->ctx, o->enable);
        c->drive_on = o->enable && rc == HAL_OK;
    }
    if (rc == HAL_OK && c->drive_on) {
        rc = a->command_current(a->ctx, o->current_a);
    }
    if (rc == HAL_OK) {
        return 0u;
    }
    c->stop_latched = true;
    if (c->drive_on) {
        (void)a->enable(a->ctx, false);
        c->drive_on = false;
    }
    return HD_FAULT_DRIVE_FAULT;
}

void hd_fw_control_boot(hd_fw_t *fw)
{
    const hd_fw_settings_t *set = hd_fw_live(fw);
    hd_ctrl_start(&fw->control.ctrl, &set->ctrl);
    fw->control.built_from = set;
    fw->control.built_gen = set->ctrl_gen;
}

uint32_t hd_fw_control(hd_fw_t *fw, const hd_fw_sample_t *s, uint32_t faults)
{
    if (!hd_fw_has_drive(fw)) {
        return 0u;
    }
    hd_fw_ctrl_state_t *c = &fw->control;
    const hd_fw_settings_t *set = hd_fw_live(fw);
    if (c->built_from != set) {
        /* new settings: the law moves to their plan (the old buffer becomes
         * the background's spare), restarting only when more than its motor
         * orders changed; a filter block switched keeps the loop's state */
        if (set->ctrl_gen != c->built_gen) {
            hd_ctrl_start(&c->ctrl, &set->ctrl);
            c->built_gen = set->ctrl_gen;
        } else {
            hd_ctrl_replan(&c->ctrl, &set->ctrl);
        }
        c->built_from = set;
    }
    track_angle(c, s, set);
    score_deadline_misses(fw);
    uint32_t raised = drive_status(fw);
    hd_ctrl_setpoint_t sp = c->sp;
    sp.mode = safe_mode(fw, faults, &raised);
    sp.kp_nm_rad = c->kp_nm_rad;
    sp.kd_nm_s_rad = c->kd_nm_s_rad;
    c->in = (hd_ctrl_input_t){
        .torque_filtered_nm = s->torque_filtered_nm,
        .torque_raw_nm = s->torque_raw_nm,
        .torque_valid = s->valid && (faults & (SENSOR_FAULTS | HD_FAULT_KF_RESET)) == 0u,
        .angle_rad = c->angle_rad + c->angle_fine_rad,
        .velocity_rad_s = hd_fw_live_pipe(fw)->output_track.vel_rad_s,
        .motor_angle_rad = hd_fw_encoder_motor_rad(&fw->encoder, set),
        .motor_angle_valid = fw->encoder.pos_valid,
    };
    hd_ctrl_step(&c->ctrl, &sp, &c->in, &c->out);
    if ((c->out.limits & HD_CTRL_LIM_FALLBACK) != 0u) {
        raised |= HD_FAULT_CTRL_FALLBACK;
    }
    hd_ctrl_output_t to_drive = c->out;
    to_drive.current_a = hd_fw_ident_drive(&fw->ident, &c->out, set->ctrl.cfg.current_limit_a);
    raised |= command_drive(fw, &to_drive);
    if (c->sp_age_ticks < UINT32_MAX) {
        c->sp_age_ticks++;
    }
    return raised;
}
