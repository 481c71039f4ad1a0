/* hd_fw_publish: the telemetry scheduler stage (hd_fw_stages.h).
 *
 * Contract: the last stage of every tick.  It sends what the tick sends:
 * the BOOT report once, a TELEM_A/B pair every telem_divider ticks (with
 * the faults and filter status gathered since the last pair; TELEM_C with
 * every angle_telemetry_every-th pair; CTRL_STATE with it on a board with a
 * drive), the heartbeat every HD_FW_HEARTBEAT_TICKS, at most
 * HD_FW_ACKS_PER_TICK queued ACKs.  A failed send is counted and raised
 * with the next sample (CAN_TX_FULL / CAN_BUS_OFF).  The tick owns the
 * transmitter. */
#include <math.h> /* isfinite, NAN: compiler builtins, no libm call */
#include <string.h>

#include "hd_fw.h"
#include "hd_fw_internal.h"

/* --------------------------------------------------------------- publish */

static void send_frame(hd_fw_t *fw, const hal_can_frame_t *f)
{
    const hal_can_t *can = &fw->hal->can;
    if (can->send == NULL) {
        return;
    }
    int rc = can->send(can->ctx, f);
    if (rc == HAL_OK) {
        return;
    }
    /* Dropped: the fault shows in the next frame that gets through. */
    fw->counters.frames_dropped++;
    fw->tick.pending_faults |= (rc == HAL_ERR_FAULT) ? HD_FAULT_CAN_BUS_OFF : HD_FAULT_CAN_TX_FULL;
}

static void send_boot(hd_fw_t *fw)
{
    const hd_fw_settings_t *set = hd_fw_live(fw);
    const hal_boot_info_t *b = &fw->bg.boot;
    hd_can_boot_t boot = {(uint8_t)b->reset_cause, b->fault_valid, fw->bg.config_from_record,
                          b->fault_valid ? b->fault_pc : 0u, (uint8_t)HD_CAN_PROTOCOL_VERSION,
                          set->config_status};
    hal_can_frame_t f;
    hd_can_encode_boot(set->cfg.node_id, &boot, &f);
    send_frame(fw, &f);
    fw->telem.boot_sent = true;
}

/* Returns true on the ticks it sends a TELEM_A/B pair. */
static bool send_telemetry(hd_fw_t *fw, const hd_fw_sample_t *s)
{
    const hd_fw_settings_t *set = hd_fw_live(fw);
    hd_fw_telem_t *k = &fw->telem;
    if (set->telem_divider == 0u) {
        return false;
    }
    if (k->countdown > 0u) {
        k->countdown--;
        return false;
    }
    k->countdown = set->telem_divider - 1u;
    hd_can_telem_t t = {s->torque_filtered_nm, s->torque_raw_nm, s->ripple_nm, s->valid,
                        s->motor_velocity_rad_s, k->faults, k->kf_status,
                        k->seq};
    k->faults = 0u;
    k->kf_status = 0u;
    hal_can_frame_t a;
    hal_can_frame_t b;
    hd_can_encode_telem(set->cfg.node_id, &t, &a, &b);
    send_frame(fw, &a);
    send_frame(fw, &b);
    const uint16_t every = set->cfg.angle_telemetry_every;
    if (every != 0u && k->pairs % every == 0u) {
        hd_can_angle_t c = {s->motor_counts, s->output_counts, s->has_output, k->seq};
        hd_can_encode_angle(set->cfg.node_id, &c, &a);
        send_frame(fw, &a);
    }
    k->pairs++;
    k->seq++;
    fw->counters.telemetry_frames++;
    return true;
}

/* CTRL_STATE with each telemetry pair (only with a drive: a board without
 * one sends what it always did), and the ACK of a refused SETPOINT/GAINS. */
static void send_control(hd_fw_t *fw, bool telemetry_tick)
{
    hd_fw_ctrl_state_t *c = &fw->control;
    const uint8_t node = hd_fw_live(fw)->cfg.node_id;
    hal_can_frame_t f;
    if (c->refuse_pending) {
        c->refuse_pending = false;
        const hd_can_ack_t a = {HD_CMD_SETPOINT_REFUSED, c->refuse_token, c->refuse_result,
                                c->refuse_aux, 0.0f, 0u};
        hd_can_encode_ack(c->refuse_node, &a, &f);
        send_frame(fw, &f);
    }
    if (fw->ident.frame_pending) {
        fw->ident.frame_pending = false;
        hd_can_encode_ident(node, &fw->ident.frame, &f);
        send_frame(fw, &f);
    }
    if (!telemetry_tick || !hd_fw_has_drive(fw)) {
        return;
    }
    const uint8_t flags = (uint8_t)((c->out.enable ? HD_CAN_CTRL_FLAG_ENABLED : 0u) |
                                    (c->watchdog ? HD_CAN_CTRL_FLAG_WATCHDOG : 0u) |
                                    (c->stop_latched ? HD_CAN_CTRL_FLAG_LATCHED : 0u));
    const hd_can_ctrl_state_t st = {(uint8_t)c->sp.mode, (uint8_t)c->out.mode, c->out.limits,
                                    c->out.torque_ref_nm, c->out.current_a, c->sp_seq, flags};
    hd_can_encode_ctrl_state(node, &st, &f);
    send_frame(fw, &f);
}

static uint16_t sat16(uint32_t v)
{
    return v > 0xFFFFu ? 0xFFFFu : (uint16_t)v;
}

static void send_heartbeat(hd_fw_t *fw, bool now)
{
    hd_fw_telem_t *k = &fw->telem;
    if (k->hb_countdown > 0u && !now) {
        k->hb_countdown--;
        return;
    }
    k->hb_countdown = HD_FW_HEARTBEAT_TICKS - 1u;
    const hd_fw_settings_t *set = hd_fw_live(fw);
    hd_can_heartbeat_t h = {fw->tick.state, k->hb_faults, sat16(fw->counters.deadline_misses),
                            set->calib_status, set->config_status, set->profile_status};
    k->hb_faults = 0u;
    hal_can_frame_t f;
    hd_can_encode_heartbeat(set->cfg.node_id, &h, &f);
    send_frame(fw, &f);
}

/* ACKs were encoded by the background; the tick owns the transmitter. */
static void send_acks(hd_fw_t *fw)
{
    hal_can_frame_t f;
    for (unsigned i = 0; i < HD_FW_ACKS_PER_TICK && hd_fw_queue_pop(&fw->ack_queue, &f); i++) {
        send_frame(fw, &f);
    }
}

void hd_fw_publish(hd_fw_t *fw, const hd_fw_sample_t *s)
{
    if (!fw->telem.boot_sent) {
        send_boot(fw);
    }
    const bool telemetry_tick = send_telemetry(fw, s);
    send_control(fw, telemetry_tick);
    send_heartbeat(fw, false);
    send_acks(fw);
}

void hd_fw_stop(hd_fw_t *fw)
{
    fw->tick.ended = true;
    fw->tick.state = HD_STATE_STOPPED;
    send_heartbeat(fw, true); /* say so at once */
    send_acks(fw);
}
