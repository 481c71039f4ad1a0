/* hd_can_gen.c: pack / unpack / encode / decode of every frame but the commands' (hd_can_gen_cmd.c).
 * Generated from firmware/hd_protocol.def by `cd tools && ../.venv/bin/python -m hdtools.protocol --write`: do not edit. */
#include "hd_can_proto.h"

#include <math.h> /* isfinite: a compiler builtin, no libm call */
#include <string.h>

#include "hd_can_gen_internal.h"

void hd_can_pack_setpoint(const hd_can_setpoint_t *v, uint8_t data[HD_CAN_DLC])
{
    uint64_t w = 0u;
    w |= (uint64_t)(v->mode & 0xFFu) << 0;
    w |= (uint64_t)(v->seq & 0xFFu) << 8;
    w |= (uint64_t)((uint32_t)hd_can_scale_int(v->torque_nm, HD_CAN_SETPOINT_TORQUE_NM_LSB, 32767) & 0xFFFFu) << 16;
    w |= (uint64_t)((uint32_t)hd_can_scale_int(v->position_rad, HD_CAN_SETPOINT_POSITION_RAD_LSB, 32767) & 0xFFFFu) << 32;
    w |= (uint64_t)((uint32_t)hd_can_scale_int(v->velocity_rad_s, HD_CAN_SETPOINT_VELOCITY_RAD_S_LSB, 32767) & 0xFFFFu) << 48;
    store_word(data, w);
}

uint32_t hd_can_unpack_setpoint(const uint8_t data[HD_CAN_DLC], hd_can_setpoint_t *v)
{
    const uint64_t w = load_word(data);
    uint32_t na = 0u;
    v->mode = (uint8_t)((uint32_t)(w >> 0) & 0xFFu);
    v->seq = (uint8_t)((uint32_t)(w >> 8) & 0xFFu);
    { const int32_t r = sext((uint32_t)(w >> 16) & 0xFFFFu, 16);
      v->torque_nm = (float)r * HD_CAN_SETPOINT_TORQUE_NM_LSB;
      na |= (r == -32768) ? (1u << 2) : 0u; }
    { const int32_t r = sext((uint32_t)(w >> 32) & 0xFFFFu, 16);
      v->position_rad = (float)r * HD_CAN_SETPOINT_POSITION_RAD_LSB;
      na |= (r == -32768) ? (1u << 3) : 0u; }
    { const int32_t r = sext((uint32_t)(w >> 48) & 0xFFFFu, 16);
      v->velocity_rad_s = (float)r * HD_CAN_SETPOINT_VELOCITY_RAD_S_LSB;
      na |= (r == -32768) ? (1u << 4) : 0u; }
    return na;
}

void hd_can_encode_setpoint(uint8_t node_id, const hd_can_setpoint_t *v, hal_can_frame_t *f)
{
    hd_can_frame_init(f, HD_CAN_FRAME_SETPOINT, node_id);
    hd_can_pack_setpoint(v, f->data);
}

int hd_can_decode_setpoint(const hal_can_frame_t *f, hd_can_setpoint_t *v)
{
    const int rc = hd_can_rx_check(f);
    if (rc != HD_CAN_RES_OK) {
        return rc;
    }
    return hd_can_unpack_setpoint(f->data, v) == 0u ? HD_CAN_RES_OK : HD_CAN_RES_NOT_FINITE;
}

void hd_can_pack_feedforward(const hd_can_feedforward_t *v, uint8_t data[HD_CAN_DLC])
{
    uint64_t w = 0u;
    w |= (uint64_t)f32_bits(v->torque_nm) << 0;
    w |= (uint64_t)(v->seq & 0xFFu) << 32;
    store_word(data, w);
}

uint32_t hd_can_unpack_feedforward(const uint8_t data[HD_CAN_DLC], hd_can_feedforward_t *v)
{
    const uint64_t w = load_word(data);
    uint32_t na = 0u;
    v->torque_nm = bits_f32((uint32_t)(w >> 0) & 0xFFFFFFFFu);
    na |= isfinite(v->torque_nm) ? 0u : (1u << 0);
    v->seq = (uint8_t)((uint32_t)(w >> 32) & 0xFFu);
    return na;
}

void hd_can_encode_feedforward(uint8_t node_id, const hd_can_feedforward_t *v, hal_can_frame_t *f)
{
    hd_can_frame_init(f, HD_CAN_FRAME_FEEDFORWARD, node_id);
    hd_can_pack_feedforward(v, f->data);
}

int hd_can_decode_feedforward(const hal_can_frame_t *f, hd_can_feedforward_t *v)
{
    const int rc = hd_can_rx_check(f);
    if (rc != HD_CAN_RES_OK) {
        return rc;
    }
    return hd_can_unpack_feedforward(f->data, v) == 0u ? HD_CAN_RES_OK : HD_CAN_RES_NOT_FINITE;
}

void hd_can_pack_telem_a(const hd_can_telem_a_t *v, uint8_t data[HD_CAN_DLC])
{
    uint64_t w = 0u;
    w |= (uint64_t)((uint32_t)hd_can_scale_int(v->torque_filtered_nm, HD_CAN_TELEM_A_TORQUE_FILTERED_NM_LSB, 32767) & 0xFFFFu) << 0;
    w |= (uint64_t)((uint32_t)hd_can_scale_int(v->torque_raw_nm, HD_CAN_TELEM_A_TORQUE_RAW_NM_LSB, 32767) & 0xFFFFu) << 16;
    w |= (uint64_t)((uint32_t)hd_can_scale_int(v->ripple_nm, HD_CAN_TELEM_A_RIPPLE_NM_LSB, 32767) & 0xFFFFu) << 32;
    w |= (uint64_t)(v->seq & 0xFFu) << 48;
    store_word(data, w);
}

uint32_t hd_can_unpack_telem_a(const uint8_t data[HD_CAN_DLC], hd_can_telem_a_t *v)
{
    const uint64_t w = load_word(data);
    uint32_t na = 0u;
    { const int32_t r = sext((uint32_t)(w >> 0) & 0xFFFFu, 16);
      v->torque_filtered_nm = (float)r * HD_CAN_TELEM_A_TORQUE_FILTERED_NM_LSB;
      na |= (r == -32768) ? (1u << 0) : 0u; }
    { const int32_t r = sext((uint32_t)(w >> 16) & 0xFFFFu, 16);
      v->torque_raw_nm = (float)r * HD_CAN_TELEM_A_TORQUE_RAW_NM_LSB;
      na |= (r == -32768) ? (1u << 1) : 0u; }
    { const int32_t r = sext((uint32_t)(w >> 32) & 0xFFFFu, 16);
      v->ripple_nm = (float)r * HD_CAN_TELEM_A_RIPPLE_NM_LSB;
      na |= (r == -32768) ? (1u << 2) : 0u; }
    v->seq = (uint8_t)((uint32_t)(w >> 48) & 0xFFu);
    return na;
}

void hd_can_encode_telem_a(uint8_t node_id, const hd_can_telem_a_t *v, hal_can_frame_t *f)
{
    hd_can_frame_init(f, HD_CAN_FRAME_TELEM_A, node_id);
    hd_can_pack_telem_a(v, f->data);
}

int hd_can_decode_telem_a(const hal_can_frame_t *f, hd_can_telem_a_t *v)
{
    if (!hd_can_frame_is(f, HD_CAN_FRAME_TELEM_A, NULL)) {
        return -1;
    }
    (void)hd_can_unpack_telem_a(f->data, v);
    return 0;
}

void hd_can_pack_telem_b(const hd_can_telem_b_t *v, uint8_t data[HD_CAN_DLC])
{
    uint64_t w = 0u;
    w |= (uint64_t)((uint32_t)hd_can_scale_int(v->motor_velocity_rad_s, HD_CAN_TELEM_B_MOTOR_VELOCITY_RAD_S_LSB, 8388607) & 0xFFFFFFu) << 0;
    w |= (uint64_t)(v->faults & 0xFFFFFFu) << 24;
    w |= (uint64_t)(v->kf_status & 0xFFu) << 48;
    w |= (uint64_t)(v->seq & 0xFFu) << 56;
    store_word(data, w);
}

uint32_t hd_can_unpack_telem_b(const uint8_t data[HD_CAN_DLC], hd_can_telem_b_t *v)
{
    const uint64_t w = load_word(data);
    uint32_t na = 0u;
    { const int32_t r = sext((uint32_t)(w >> 0) & 0xFFFFFFu, 24);
      v->motor_velocity_rad_s = (float)r * HD_CAN_TELEM_B_MOTOR_VELOCITY_RAD_S_LSB;
      na |= (r == -8388608) ? (1u << 0) : 0u; }
    v->faults = (uint32_t)((uint32_t)(w >> 24) & 0xFFFFFFu);
    v->kf_status = (uint8_t)((uint32_t)(w >> 48) & 0xFFu);
    v->seq = (uint8_t)((uint32_t)(w >> 56) & 0xFFu);
    return na;
}

void hd_can_encode_telem_b(uint8_t node_id, const hd_can_telem_b_t *v, hal_can_frame_t *f)
{
    hd_can_frame_init(f, HD_CAN_FRAME_TELEM_B, node_id);
    hd_can_pack_telem_b(v, f->data);
}

int hd_can_decode_telem_b(const hal_can_frame_t *f, hd_can_telem_b_t *v)
{
    if (!hd_can_frame_is(f, HD_CAN_FRAME_TELEM_B, NULL)) {
        return -1;
    }
    (void)hd_can_unpack_telem_b(f->data, v);
    return 0;
}

void hd_can_pack_telem_c(const hd_can_telem_c_t *v, uint8_t data[HD_CAN_DLC])
{
    uint64_t w = 0u;
    w |= (uint64_t)(v->motor_counts & 0xFFFFFFFFu) << 0;
    w |= (uint64_t)(v->output_counts & 0x7FFFFFu) << 32;
    w |= (uint64_t)(v->has_output ? 1u : 0u) << 55;
    w |= (uint64_t)(v->seq & 0xFFu) << 56;
    store_word(data, w);
}

uint32_t hd_can_unpack_telem_c(const uint8_t data[HD_CAN_DLC], hd_can_telem_c_t *v)
{
    const uint64_t w = load_word(data);
    uint32_t na = 0u;
    v->motor_counts = (uint32_t)((uint32_t)(w >> 0) & 0xFFFFFFFFu);
    v->output_counts = (uint32_t)((uint32_t)(w >> 32) & 0x7FFFFFu);
    v->has_output = (((uint32_t)(w >> 55) & 0x1u) != 0u);
    v->seq = (uint8_t)((uint32_t)(w >> 56) & 0xFFu);
    return na;
}

void hd_can_encode_telem_c(uint8_t node_id, const hd_can_telem_c_t *v, hal_can_frame_t *f)
{
    hd_can_frame_init(f, HD_CAN_FRAME_TELEM_C, node_id);
    hd_can_pack_telem_c(v, f->data);
}

int hd_can_decode_telem_c(const hal_can_frame_t *f, hd_can_telem_c_t *v)
{
    if (!hd_can_frame_is(f, HD_CAN_FRAME_TELEM_C, NULL)) {
        return -1;
    }
    (void)hd_can_unpack_telem_c(f->data, v);
    return 0;
}

void hd_can_pack_gains(const hd_can_gains_t *v, uint8_t data[HD_CAN_DLC])
{
    uint64_t w = 0u;
    w |= (uint64_t)f32_bits(v->kp_nm_rad) << 0;
    w |= (uint64_t)f32_bits(v->kd_nm_s_rad) << 32;
    store_word(data, w);
}

uint32_t hd_can_unpack_gains(const uint8_t data[HD_CAN_DLC], hd_can_gains_t *v)
{
    const uint64_t w = load_word(data);
    uint32_t na = 0u;
    v->kp_nm_rad = bits_f32((uint32_t)(w >> 0) & 0xFFFFFFFFu);
    na |= isfinite(v->kp_nm_rad) ? 0u : (1u << 0);
    v->kd_nm_s_rad = bits_f32((uint32_t)(w >> 32) & 0xFFFFFFFFu);
    na |= isfinite(v->kd_nm_s_rad) ? 0u : (1u << 1);
    return na;
}

void hd_can_encode_gains(uint8_t node_id, const hd_can_gains_t *v, hal_can_frame_t *f)
{
    hd_can_frame_init(f, HD_CAN_FRAME_GAINS, node_id);
    hd_can_pack_gains(v, f->data);
}

int hd_can_decode_gains(const hal_can_frame_t *f, hd_can_gains_t *v)
{
    const int rc = hd_can_rx_check(f);
    if (rc != HD_CAN_RES_OK) {
        return rc;
    }
    return hd_can_unpack_gains(f->data, v) == 0u ? HD_CAN_RES_OK : HD_CAN_RES_NOT_FINITE;
}

void hd_can_pack_ctrl_state(const hd_can_ctrl_state_t *v, uint8_t data[HD_CAN_DLC])
{
    uint64_t w = 0u;
    w |= (uint64_t)(v->mode_asked & 0xFu) << 0;
    w |= (uint64_t)(v->mode_run & 0xFu) << 4;
    w |= (uint64_t)(v->limits & 0xFFu) << 8;
    w |= (uint64_t)((uint32_t)hd_can_scale_int(v->torque_ref_nm, HD_CAN_CTRL_STATE_TORQUE_REF_NM_LSB, 32767) & 0xFFFFu) << 16;
    w |= (uint64_t)((uint32_t)hd_can_scale_int(v->current_a, HD_CAN_CTRL_STATE_CURRENT_A_LSB, 32767) & 0xFFFFu) << 32;
    w |= (uint64_t)(v->seq & 0xFFu) << 48;
    w |= (uint64_t)(v->flags & 0xFFu) << 56;
    store_word(data, w);
}

uint32_t hd_can_unpack_ctrl_state(const uint8_t data[HD_CAN_DLC], hd_can_ctrl_state_t *v)
{
    const uint64_t w = load_word(data);
    uint32_t na = 0u;
    v->mode_asked = (uint8_t)((uint32_t)(w >> 0) & 0xFu);
    v->mode_run = (uint8_t)((uint32_t)(w >> 4) & 0xFu);
    v->limits = (uint8_t)((uint32_t)(w >> 8) & 0xFFu);
    { const int32_t r = sext((uint32_t)(w >> 16) & 0xFFFFu, 16);
      v->torque_ref_nm = (float)r * HD_CAN_CTRL_STATE_TORQUE_REF_NM_LSB;
      na |= (r == -32768) ? (1u << 3) : 0u; }
    { const int32_t r = sext((uint32_t)(w >> 32) & 0xFFFFu, 16);
      v->current_a = (float)r * HD_CAN_CTRL_STATE_CURRENT_A_LSB;
      na |= (r == -32768) ? (1u << 4) : 0u; }
    v->seq = (uint8_t)((uint32_t)(w >> 48) & 0xFFu);
    v->flags = (uint8_t)((uint32_t)(w >> 56) & 0xFFu);
    return na;
}

void hd_can_encode_ctrl_state(uint8_t node_id, const hd_can_ctrl_state_t *v, hal_can_frame_t *f)
{
    hd_can_frame_init(f, HD_CAN_FRAME_CTRL_STATE, node_id);
    hd_can_pack_ctrl_state(v, f->data);
}

int hd_can_decode_ctrl_state(const hal_can_frame_t *f, hd_can_ctrl_state_t *v)
{
    if (!hd_can_frame_is(f, HD_CAN_FRAME_CTRL_STATE, NULL)) {
        return -1;
    }
    (void)hd_can_unpack_ctrl_state(f->data, v);
    return 0;
}

void hd_can_pack_ident(const hd_can_ident_t *v, uint8_t data[HD_CAN_DLC])
{
    uint64_t w = 0u;
    w |= (uint64_t)((uint32_t)hd_can_scale_int(v->cmd_a, HD_CAN_IDENT_CMD_A_LSB, 32767) & 0xFFFFu) << 0;
    w |= (uint64_t)((uint32_t)hd_can_scale_int(v->drive_a, HD_CAN_IDENT_DRIVE_A_LSB, 32767) & 0xFFFFu) << 16;
    w |= (uint64_t)((uint32_t)hd_can_scale_int(v->feedback_nm, HD_CAN_IDENT_FEEDBACK_NM_LSB, 32767) & 0xFFFFu) << 32;
    w |= (uint64_t)(v->tick & 0xFFu) << 48;
    w |= (uint64_t)(v->status & 0xFFu) << 56;
    store_word(data, w);
}

uint32_t hd_can_unpack_ident(const uint8_t data[HD_CAN_DLC], hd_can_ident_t *v)
{
    const uint64_t w = load_word(data);
    uint32_t na = 0u;
    { const int32_t r = sext((uint32_t)(w >> 0) & 0xFFFFu, 16);
      v->cmd_a = (float)r * HD_CAN_IDENT_CMD_A_LSB;
      na |= (r == -32768) ? (1u << 0) : 0u; }
    { const int32_t r = sext((uint32_t)(w >> 16) & 0xFFFFu, 16);
      v->drive_a = (float)r * HD_CAN_IDENT_DRIVE_A_LSB;
      na |= (r == -32768) ? (1u << 1) : 0u; }
    { const int32_t r = sext((uint32_t)(w >> 32) & 0xFFFFu, 16);
      v->feedback_nm = (float)r * HD_CAN_IDENT_FEEDBACK_NM_LSB;
      na |= (r == -32768) ? (1u << 2) : 0u; }
    v->tick = (uint8_t)((uint32_t)(w >> 48) & 0xFFu);
    v->status = (uint8_t)((uint32_t)(w >> 56) & 0xFFu);
    return na;
}

void hd_can_encode_ident(uint8_t node_id, const hd_can_ident_t *v, hal_can_frame_t *f)
{
    hd_can_frame_init(f, HD_CAN_FRAME_IDENT, node_id);
    hd_can_pack_ident(v, f->data);
}

int hd_can_decode_ident(const hal_can_frame_t *f, hd_can_ident_t *v)
{
    if (!hd_can_frame_is(f, HD_CAN_FRAME_IDENT, NULL)) {
        return -1;
    }
    (void)hd_can_unpack_ident(f->data, v);
    return 0;
}

void hd_can_pack_heartbeat(const hd_can_heartbeat_t *v, uint8_t data[HD_CAN_DLC])
{
    uint64_t w = 0u;
    w |= (uint64_t)(v->state & 0xFFu) << 0;
    w |= (uint64_t)(v->faults & 0xFFFFFFu) << 8;
    w |= (uint64_t)(v->deadline_misses & 0xFFFFu) << 32;
    w |= (uint64_t)(v->calib_status & 0xFu) << 48;
    w |= (uint64_t)(v->config_status & 0xFu) << 52;
    w |= (uint64_t)(v->profile_status & 0xFFu) << 56;
    store_word(data, w);
}

uint32_t hd_can_unpack_heartbeat(const uint8_t data[HD_CAN_DLC], hd_can_heartbeat_t *v)
{
    const uint64_t w = load_word(data);
    uint32_t na = 0u;
    v->state = (uint8_t)((uint32_t)(w >> 0) & 0xFFu);
    v->faults = (uint32_t)((uint32_t)(w >> 8) & 0xFFFFFFu);
    v->deadline_misses = (uint16_t)((uint32_t)(w >> 32) & 0xFFFFu);
    v->calib_status = (uint8_t)((uint32_t)(w >> 48) & 0xFu);
    v->config_status = (uint8_t)((uint32_t)(w >> 52) & 0xFu);
    v->profile_status = (uint8_t)((uint32_t)(w >> 56) & 0xFFu);
    return na;
}

void hd_can_encode_heartbeat(uint8_t node_id, const hd_can_heartbeat_t *v, hal_can_frame_t *f)
{
    hd_can_frame_init(f, HD_CAN_FRAME_HEARTBEAT, node_id);
    hd_can_pack_heartbeat(v, f->data);
}

int hd_can_decode_heartbeat(const hal_can_frame_t *f, hd_can_heartbeat_t *v)
{
    if (!hd_can_frame_is(f, HD_CAN_FRAME_HEARTBEAT, NULL)) {
        return -1;
    }
    (void)hd_can_unpack_heartbeat(f->data, v);
    return 0;
}

void hd_can_pack_boot(const hd_can_boot_t *v, uint8_t data[HD_CAN_DLC])
{
    uint64_t w = 0u;
    w |= (uint64_t)(v->reset_cause & 0xFFu) << 0;
    w |= (uint64_t)(v->fault_valid ? 1u : 0u) << 8;
    w |= (uint64_t)(v->config_from_record ? 1u : 0u) << 9;
    w |= (uint64_t)(v->fault_pc & 0xFFFFFFFFu) << 16;
    w |= (uint64_t)(v->protocol_version & 0xFFu) << 48;
    w |= (uint64_t)(v->config_status & 0xFFu) << 56;
    store_word(data, w);
}

uint32_t hd_can_unpack_boot(const uint8_t data[HD_CAN_DLC], hd_can_boot_t *v)
{
    const uint64_t w = load_word(data);
    uint32_t na = 0u;
    v->reset_cause = (uint8_t)((uint32_t)(w >> 0) & 0xFFu);
    v->fault_valid = (((uint32_t)(w >> 8) & 0x1u) != 0u);
    v->config_from_record = (((uint32_t)(w >> 9) & 0x1u) != 0u);
    v->fault_pc = (uint32_t)((uint32_t)(w >> 16) & 0xFFFFFFFFu);
    v->protocol_version = (uint8_t)((uint32_t)(w >> 48) & 0xFFu);
    v->config_status = (uint8_t)((uint32_t)(w >> 56) & 0xFFu);
    return na;
}

void hd_can_encode_boot(uint8_t node_id, const hd_can_boot_t *v, hal_can_frame_t *f)
{
    hd_can_frame_init(f, HD_CAN_FRAME_BOOT, node_id);
    hd_can_pack_boot(v, f->data);
}

int hd_can_decode_boot(const hal_can_frame_t *f, hd_can_boot_t *v)
{
    if (!hd_can_frame_is(f, HD_CAN_FRAME_BOOT, NULL)) {
        return -1;
    }
    (void)hd_can_unpack_boot(f->data, v);
    return 0;
}
