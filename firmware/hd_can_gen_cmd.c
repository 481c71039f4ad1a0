/* hd_can_gen_cmd.c: pack / unpack / encode / decode of the command frames (CMD, ACK) and the opcode predicates.
 * Generated from firmware/hd_protocol.def by `cd tools && ../.venv/bin/python -m hdtools.protocol --write`: do not edit. */
#include "hd_can_proto.h"

#include <math.h> /* isfinite: a compiler builtin, no libm call */
#include <string.h>

#include "hd_can_gen_internal.h"

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
    case 0x74u: /* IDENT_START */
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
    case HD_CMD_IDENT_START:
        w |= (uint64_t)(v->arg.ident_start.periods & 0xFFu) << 16;
        w |= (uint64_t)f32_bits(v->arg.ident_start.rms_a) << 32;
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
    case HD_CMD_IDENT_START:
        v->arg.ident_start.periods = (uint8_t)((uint32_t)(w >> 16) & 0xFFu);
        v->arg.ident_start.rms_a = bits_f32((uint32_t)(w >> 32) & 0xFFFFFFFFu);
        na |= isfinite(v->arg.ident_start.rms_a) ? 0u : (1u << 1);
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
