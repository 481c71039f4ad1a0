/* hd_can_gen.c: pack / unpack / encode / decode of every frame.
 * Generated from firmware/hd_protocol.def by `cd tools && ../.venv/bin/python -m hdtools.protocol --write`: do not edit. */
#include "hd_can_proto.h"

#include <math.h> /* isfinite: a compiler builtin, no libm call */
#include <string.h>

static uint32_t f32_bits(float v) { uint32_t u; memcpy(&u, &v, sizeof u); return u; }
static float bits_f32(uint32_t u) { float v; memcpy(&v, &u, sizeof v); return v; }
static int32_t sext(uint32_t raw, unsigned bits)
{
    const uint32_t sign = 1u << (bits - 1u);
    return (int32_t)(raw ^ sign) - (int32_t)sign;
}
/* Two 32-bit halves with constant shifts: a loop over a 64-bit
 * variable shift costs the Cortex-M4 a libgcc-style sequence per byte. */
static uint32_t load_u32(const uint8_t *d)
{
    return (uint32_t)d[0] | (uint32_t)d[1] << 8 | (uint32_t)d[2] << 16 | (uint32_t)d[3] << 24;
}
static uint64_t load_word(const uint8_t *d)
{
    return (uint64_t)load_u32(d) | (uint64_t)load_u32(d + 4) << 32;
}
static void store_u32(uint8_t *d, uint32_t u)
{
    d[0] = (uint8_t)u;
    d[1] = (uint8_t)(u >> 8);
    d[2] = (uint8_t)(u >> 16);
    d[3] = (uint8_t)(u >> 24);
}
static void store_word(uint8_t *d, uint64_t w)
{
    store_u32(d, (uint32_t)w);
    store_u32(d + 4, (uint32_t)(w >> 32));
}

bool hd_can_is_command(uint8_t opcode)
{
    switch (opcode) {
    case 0x01u: /* FILTER_ENABLE */
    case 0x10u: /* ADD_MOTOR */
    case 0x11u: /* ADD_OUTPUT */
    case 0x12u: /* ADD_FIXED */
    case 0x13u: /* BLOCK_ENABLE */
    case 0x14u: /* BLOCKS_CLEAR */
    case 0x15u: /* BLOCK_GET */
    case 0x20u: /* SET_PARAM */
    case 0x21u: /* GET_PARAM */
    case 0x30u: /* TARE */
    case 0x31u: /* CALIB_SAVE */
    case 0x32u: /* CALIB_LOAD */
    case 0x40u: /* FILTER_RESET */
    case 0x50u: /* CONFIG_SAVE */
    case 0x51u: /* CONFIG_LOAD */
    case 0x52u: /* CONFIG_DEFAULTS */
    case 0x60u: /* VERSION */
    case 0x61u: /* INFO */
    case 0x62u: /* REBOOT */
    case 0x70u: /* PROFILE_SAVE */
    case 0x71u: /* PROFILE_LOAD */
    case 0x72u: /* PROFILE_CLEAR */
    case 0x73u: /* PROFILE_PUT */
        return true;
    default:
        return false;
    }
}

bool hd_can_ack_is_u32(uint8_t opcode)
{
    switch (opcode) {
    case HD_CMD_VERSION:
    case HD_CMD_INFO:
        return true;
    default:
        return false;
    }
}

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

void hd_can_pack_cmd(const hd_can_cmd_t *v, uint8_t data[HD_CAN_DLC])
{
    uint64_t w = 0u;
    w |= (uint64_t)(v->opcode & 0xFFu) << 0;
    w |= (uint64_t)(v->token & 0xFFu) << 8;
    switch (v->opcode) {
    case HD_CMD_FILTER_ENABLE:
        w |= (uint64_t)(v->arg.filter_enable.enable & 0xFFu) << 16;
        break;
    case HD_CMD_ADD_MOTOR:
        w |= (uint64_t)hd_can_scale_uq(v->arg.add_motor.order, HD_CAN_ADD_MOTOR_ORDER_DIV, 65535.0f) << 16;
        w |= (uint64_t)f32_bits(v->arg.add_motor.q_nm2) << 32;
        break;
    case HD_CMD_ADD_OUTPUT:
        w |= (uint64_t)hd_can_scale_uq(v->arg.add_output.order, HD_CAN_ADD_OUTPUT_ORDER_DIV, 65535.0f) << 16;
        w |= (uint64_t)f32_bits(v->arg.add_output.q_nm2) << 32;
        break;
    case HD_CMD_ADD_FIXED:
        w |= (uint64_t)hd_can_scale_uq(v->arg.add_fixed.frequency_hz, HD_CAN_ADD_FIXED_FREQUENCY_HZ_DIV, 65535.0f) << 16;
        w |= (uint64_t)f32_bits(v->arg.add_fixed.q_nm2) << 32;
        break;
    case HD_CMD_BLOCK_ENABLE:
        w |= (uint64_t)(v->arg.block_enable.index & 0xFFu) << 16;
        w |= (uint64_t)(v->arg.block_enable.enable & 0xFFu) << 24;
        break;
    case HD_CMD_BLOCK_GET:
        w |= (uint64_t)(v->arg.block_get.index & 0xFFu) << 16;
        w |= (uint64_t)(v->arg.block_get.field & 0xFFu) << 24;
        break;
    case HD_CMD_SET_PARAM:
        w |= (uint64_t)(v->arg.set_param.id & 0xFFu) << 16;
        w |= (uint64_t)f32_bits(v->arg.set_param.value) << 32;
        break;
    case HD_CMD_GET_PARAM:
        w |= (uint64_t)(v->arg.get_param.id & 0xFFu) << 16;
        break;
    case HD_CMD_CALIB_SAVE:
        w |= (uint64_t)(v->arg.calib_save.calibrated_unix_s & 0xFFFFFFFFu) << 32;
        break;
    case HD_CMD_VERSION:
        w |= (uint64_t)(v->arg.version.item & 0xFFu) << 16;
        break;
    case HD_CMD_INFO:
        w |= (uint64_t)(v->arg.info.item & 0xFFu) << 16;
        break;
    case HD_CMD_PROFILE_SAVE:
        w |= (uint64_t)(v->arg.profile_save.source & 0xFFu) << 16;
        break;
    case HD_CMD_PROFILE_LOAD:
        w |= (uint64_t)(v->arg.profile_load.source & 0xFFu) << 16;
        break;
    case HD_CMD_PROFILE_PUT:
        w |= (uint64_t)(v->arg.profile_put.line & 0xFFu) << 16;
        w |= (uint64_t)(v->arg.profile_put.order & 0xFFu) << 24;
        w |= (uint64_t)f32_bits(v->arg.profile_put.value_nm) << 32;
        break;
    default:
        break;
    }
    store_word(data, w);
}

uint32_t hd_can_unpack_cmd(const uint8_t data[HD_CAN_DLC], hd_can_cmd_t *v)
{
    const uint64_t w = load_word(data);
    uint32_t na = 0u;
    memset(v, 0, sizeof *v);
    v->opcode = (uint8_t)((uint32_t)(w >> 0) & 0xFFu);
    v->token = (uint8_t)((uint32_t)(w >> 8) & 0xFFu);
    switch (v->opcode) {
    case HD_CMD_FILTER_ENABLE:
        v->arg.filter_enable.enable = (uint8_t)((uint32_t)(w >> 16) & 0xFFu);
        break;
    case HD_CMD_ADD_MOTOR:
        v->arg.add_motor.order = (float)((uint32_t)(w >> 16) & 0xFFFFu) / HD_CAN_ADD_MOTOR_ORDER_DIV;
        v->arg.add_motor.q_nm2 = bits_f32((uint32_t)(w >> 32) & 0xFFFFFFFFu);
        na |= isfinite(v->arg.add_motor.q_nm2) ? 0u : (1u << 1);
        break;
    case HD_CMD_ADD_OUTPUT:
        v->arg.add_output.order = (float)((uint32_t)(w >> 16) & 0xFFFFu) / HD_CAN_ADD_OUTPUT_ORDER_DIV;
        v->arg.add_output.q_nm2 = bits_f32((uint32_t)(w >> 32) & 0xFFFFFFFFu);
        na |= isfinite(v->arg.add_output.q_nm2) ? 0u : (1u << 1);
        break;
    case HD_CMD_ADD_FIXED:
        v->arg.add_fixed.frequency_hz = (float)((uint32_t)(w >> 16) & 0xFFFFu) / HD_CAN_ADD_FIXED_FREQUENCY_HZ_DIV;
        v->arg.add_fixed.q_nm2 = bits_f32((uint32_t)(w >> 32) & 0xFFFFFFFFu);
        na |= isfinite(v->arg.add_fixed.q_nm2) ? 0u : (1u << 1);
        break;
    case HD_CMD_BLOCK_ENABLE:
        v->arg.block_enable.index = (uint8_t)((uint32_t)(w >> 16) & 0xFFu);
        v->arg.block_enable.enable = (uint8_t)((uint32_t)(w >> 24) & 0xFFu);
        break;
    case HD_CMD_BLOCK_GET:
        v->arg.block_get.index = (uint8_t)((uint32_t)(w >> 16) & 0xFFu);
        v->arg.block_get.field = (uint8_t)((uint32_t)(w >> 24) & 0xFFu);
        break;
    case HD_CMD_SET_PARAM:
        v->arg.set_param.id = (uint8_t)((uint32_t)(w >> 16) & 0xFFu);
        v->arg.set_param.value = bits_f32((uint32_t)(w >> 32) & 0xFFFFFFFFu);
        na |= isfinite(v->arg.set_param.value) ? 0u : (1u << 1);
        break;
    case HD_CMD_GET_PARAM:
        v->arg.get_param.id = (uint8_t)((uint32_t)(w >> 16) & 0xFFu);
        break;
    case HD_CMD_CALIB_SAVE:
        v->arg.calib_save.calibrated_unix_s = (uint32_t)((uint32_t)(w >> 32) & 0xFFFFFFFFu);
        break;
    case HD_CMD_VERSION:
        v->arg.version.item = (uint8_t)((uint32_t)(w >> 16) & 0xFFu);
        break;
    case HD_CMD_INFO:
        v->arg.info.item = (uint8_t)((uint32_t)(w >> 16) & 0xFFu);
        break;
    case HD_CMD_PROFILE_SAVE:
        v->arg.profile_save.source = (uint8_t)((uint32_t)(w >> 16) & 0xFFu);
        break;
    case HD_CMD_PROFILE_LOAD:
        v->arg.profile_load.source = (uint8_t)((uint32_t)(w >> 16) & 0xFFu);
        break;
    case HD_CMD_PROFILE_PUT:
        v->arg.profile_put.line = (uint8_t)((uint32_t)(w >> 16) & 0xFFu);
        v->arg.profile_put.order = (uint8_t)((uint32_t)(w >> 24) & 0xFFu);
        v->arg.profile_put.value_nm = bits_f32((uint32_t)(w >> 32) & 0xFFFFFFFFu);
        break;
    default:
        break;
    }
    return na;
}

void hd_can_encode_cmd(uint8_t node_id, const hd_can_cmd_t *v, hal_can_frame_t *f)
{
    hd_can_frame_init(f, HD_CAN_FRAME_CMD, node_id);
    hd_can_pack_cmd(v, f->data);
}

void hd_can_pack_ack(const hd_can_ack_t *v, uint8_t data[HD_CAN_DLC])
{
    uint64_t w = 0u;
    w |= (uint64_t)(v->opcode & 0xFFu) << 0;
    w |= (uint64_t)(v->token & 0xFFu) << 8;
    w |= (uint64_t)(v->result & 0xFFu) << 16;
    w |= (uint64_t)(v->aux & 0xFFu) << 24;
    if (!hd_can_ack_is_u32(v->opcode)) {
        w |= (uint64_t)f32_bits(v->value) << 32;
    }
    if (hd_can_ack_is_u32(v->opcode)) {
        w |= (uint64_t)(v->value_u32 & 0xFFFFFFFFu) << 32;
    }
    store_word(data, w);
}

uint32_t hd_can_unpack_ack(const uint8_t data[HD_CAN_DLC], hd_can_ack_t *v)
{
    const uint64_t w = load_word(data);
    uint32_t na = 0u;
    memset(v, 0, sizeof *v);
    v->opcode = (uint8_t)((uint32_t)(w >> 0) & 0xFFu);
    v->token = (uint8_t)((uint32_t)(w >> 8) & 0xFFu);
    v->result = (uint8_t)((uint32_t)(w >> 16) & 0xFFu);
    v->aux = (uint8_t)((uint32_t)(w >> 24) & 0xFFu);
    if (!hd_can_ack_is_u32(v->opcode)) {
        v->value = bits_f32((uint32_t)(w >> 32) & 0xFFFFFFFFu);
    }
    if (hd_can_ack_is_u32(v->opcode)) {
        v->value_u32 = (uint32_t)((uint32_t)(w >> 32) & 0xFFFFFFFFu);
    }
    return na;
}

void hd_can_encode_ack(uint8_t node_id, const hd_can_ack_t *v, hal_can_frame_t *f)
{
    hd_can_frame_init(f, HD_CAN_FRAME_ACK, node_id);
    hd_can_pack_ack(v, f->data);
}

int hd_can_decode_ack(const hal_can_frame_t *f, hd_can_ack_t *v)
{
    if (!hd_can_frame_is(f, HD_CAN_FRAME_ACK, NULL)) {
        return -1;
    }
    (void)hd_can_unpack_ack(f->data, v);
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
