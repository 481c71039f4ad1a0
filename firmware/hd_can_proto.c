/* hd_can_proto: see hd_can_proto.h.  Byte layouts are documented in
 * docs/firmware.md and firmware/hdjoint.dbc; keep all three in step. */
#include "hd_can_proto.h"

#include <math.h>   /* isfinite (a compiler builtin, no libm call) */
#include <string.h>

void hd_can_put_u16(uint8_t *p, uint16_t v)
{
    p[0] = (uint8_t)(v & 0xFFu);
    p[1] = (uint8_t)(v >> 8);
}

void hd_can_put_u32(uint8_t *p, uint32_t v)
{
    p[0] = (uint8_t)(v & 0xFFu);
    p[1] = (uint8_t)((v >> 8) & 0xFFu);
    p[2] = (uint8_t)((v >> 16) & 0xFFu);
    p[3] = (uint8_t)(v >> 24);
}

void hd_can_put_f32(uint8_t *p, float v)
{
    uint32_t bits;
    memcpy(&bits, &v, sizeof bits); /* IEEE-754 binary32 on every target we build */
    hd_can_put_u32(p, bits);
}

uint16_t hd_can_get_u16(const uint8_t *p)
{
    return (uint16_t)((uint16_t)p[0] | (uint16_t)((uint16_t)p[1] << 8));
}

uint32_t hd_can_get_u32(const uint8_t *p)
{
    return (uint32_t)p[0] | ((uint32_t)p[1] << 8) | ((uint32_t)p[2] << 16) |
           ((uint32_t)p[3] << 24);
}

float hd_can_get_f32(const uint8_t *p)
{
    uint32_t bits = hd_can_get_u32(p);
    float v;
    memcpy(&v, &bits, sizeof v);
    return v;
}

int16_t hd_can_scale_i16(float value, float lsb)
{
    if (!isfinite(value)) {
        return HD_CAN_INT16_NA;
    }
    float q = value / lsb;
    if (q >= 32767.0f) {
        return INT16_MAX;
    }
    if (q <= -32767.0f) {
        return (int16_t)-32767; /* -32768 is reserved for "not available" */
    }
    return (int16_t)(q >= 0.0f ? q + 0.5f : q - 0.5f);
}

int32_t hd_can_scale_i32(float value, float lsb)
{
    if (!isfinite(value)) {
        return INT32_MIN;
    }
    float q = value / lsb;
    /* 2147483520 is the largest float below 2^31 */
    if (q >= 2147483520.0f) {
        return INT32_MAX;
    }
    if (q <= -2147483520.0f) {
        return -INT32_MAX;
    }
    return (int32_t)(q >= 0.0f ? q + 0.5f : q - 0.5f);
}

static void frame_init(hal_can_frame_t *f, uint32_t id)
{
    memset(f, 0, sizeof *f);
    f->id = id;
    f->len = HD_CAN_DLC;
}

void hd_can_encode_telem(uint8_t node_id, const hd_can_telem_t *t,
                         hal_can_frame_t *a, hal_can_frame_t *b)
{
    frame_init(a, HD_CAN_ID_TELEM_A + node_id);
    int16_t filt = t->torque_valid ? hd_can_scale_i16(t->torque_filtered_nm, HD_CAN_TORQUE_LSB_NM)
                                   : HD_CAN_INT16_NA;
    int16_t raw = t->torque_valid ? hd_can_scale_i16(t->torque_raw_nm, HD_CAN_TORQUE_LSB_NM)
                                  : HD_CAN_INT16_NA;
    hd_can_put_u16(&a->data[0], (uint16_t)filt);
    hd_can_put_u16(&a->data[2], (uint16_t)raw);
    hd_can_put_u16(&a->data[4], (uint16_t)hd_can_scale_i16(t->ripple_nm, HD_CAN_RIPPLE_LSB_NM));
    a->data[6] = t->seq;
    a->data[7] = 0;

    frame_init(b, HD_CAN_ID_TELEM_B + node_id);
    hd_can_put_u32(&b->data[0],
                   (uint32_t)hd_can_scale_i32(t->motor_velocity_rad_s, HD_CAN_VELOCITY_LSB_RAD_S));
    hd_can_put_u16(&b->data[4], t->faults);
    b->data[6] = t->kf_status;
    b->data[7] = t->seq;
}

static float i16_to_float(uint16_t raw, float lsb)
{
    int16_t v = (int16_t)raw;
    return (float)v * lsb;
}

int hd_can_decode_telem(const hal_can_frame_t *a, const hal_can_frame_t *b,
                        hd_can_telem_t *out)
{
    if (a->len != HD_CAN_DLC || b->len != HD_CAN_DLC || a->id < HD_CAN_ID_TELEM_A ||
        a->id > HD_CAN_ID_TELEM_A + HD_CAN_NODE_MAX ||
        b->id - HD_CAN_ID_TELEM_B != a->id - HD_CAN_ID_TELEM_A || a->data[6] != b->data[7]) {
        return -1;
    }
    memset(out, 0, sizeof *out);
    uint16_t filt = hd_can_get_u16(&a->data[0]);
    uint16_t raw = hd_can_get_u16(&a->data[2]);
    out->torque_valid = (int16_t)filt != HD_CAN_INT16_NA && (int16_t)raw != HD_CAN_INT16_NA;
    out->torque_filtered_nm = i16_to_float(filt, HD_CAN_TORQUE_LSB_NM);
    out->torque_raw_nm = i16_to_float(raw, HD_CAN_TORQUE_LSB_NM);
    out->ripple_nm = i16_to_float(hd_can_get_u16(&a->data[4]), HD_CAN_RIPPLE_LSB_NM);
    out->seq = a->data[6];
    out->motor_velocity_rad_s =
        (float)(int32_t)hd_can_get_u32(&b->data[0]) * HD_CAN_VELOCITY_LSB_RAD_S;
    out->faults = hd_can_get_u16(&b->data[4]);
    out->kf_status = b->data[6];
    return 0;
}

void hd_can_encode_heartbeat(uint8_t node_id, const hd_can_heartbeat_t *h,
                             hal_can_frame_t *f)
{
    frame_init(f, HD_CAN_ID_HEARTBEAT + node_id);
    f->data[0] = h->state;
    hd_can_put_u16(&f->data[1], h->faults);
    hd_can_put_u16(&f->data[3], h->deadline_misses);
    hd_can_put_u16(&f->data[5], h->fault_ticks);
    f->data[7] = h->calib_status;
}

int hd_can_decode_heartbeat(const hal_can_frame_t *f, hd_can_heartbeat_t *out)
{
    if (f->len != HD_CAN_DLC || f->id < HD_CAN_ID_HEARTBEAT ||
        f->id > HD_CAN_ID_HEARTBEAT + HD_CAN_NODE_MAX) {
        return -1;
    }
    out->state = f->data[0];
    out->faults = hd_can_get_u16(&f->data[1]);
    out->deadline_misses = hd_can_get_u16(&f->data[3]);
    out->fault_ticks = hd_can_get_u16(&f->data[5]);
    out->calib_status = f->data[7];
    return 0;
}

static bool is_add_opcode(uint8_t op)
{
    return op == HD_CMD_ADD_MOTOR || op == HD_CMD_ADD_OUTPUT || op == HD_CMD_ADD_FIXED;
}

void hd_can_encode_cmd(uint8_t node_id, const hd_can_cmd_t *c, hal_can_frame_t *f)
{
    frame_init(f, HD_CAN_ID_CMD + node_id);
    f->data[0] = c->opcode;
    f->data[1] = c->token;
    if (is_add_opcode(c->opcode)) {
        float scaled = c->order * 100.0f + 0.5f;
        uint16_t u = (scaled <= 0.0f) ? 0u : (scaled >= 65535.0f ? 65535u : (uint16_t)scaled);
        hd_can_put_u16(&f->data[2], u);
        hd_can_put_f32(&f->data[4], c->value);
    } else if (c->opcode == HD_CMD_CALIB_SAVE) {
        hd_can_put_u32(&f->data[4], c->arg_u32);
    } else {
        f->data[2] = c->arg_u8[0];
        f->data[3] = c->arg_u8[1];
        hd_can_put_f32(&f->data[4], c->value);
    }
}

int hd_can_decode_cmd(const hal_can_frame_t *f, hd_can_cmd_t *cmd)
{
    memset(cmd, 0, sizeof *cmd);
    if (f->len > 0u) {
        cmd->opcode = f->data[0];
    }
    if (f->len > 1u) {
        cmd->token = f->data[1];
    }
    if ((f->flags & (HAL_CAN_FLAG_EXT | HAL_CAN_FLAG_RTR | HAL_CAN_FLAG_ERR | HAL_CAN_FLAG_FD)) != 0u) {
        return HD_CAN_RES_BAD_FRAME;
    }
    if (f->len != HD_CAN_DLC) {
        return HD_CAN_RES_BAD_LENGTH;
    }
    cmd->arg_u8[0] = f->data[2];
    cmd->arg_u8[1] = f->data[3];
    cmd->arg_u32 = hd_can_get_u32(&f->data[4]);
    switch (cmd->opcode) {
    case HD_CMD_ADD_MOTOR:
    case HD_CMD_ADD_OUTPUT:
    case HD_CMD_ADD_FIXED:
        cmd->order = (float)hd_can_get_u16(&f->data[2]) / 100.0f;
        cmd->value = hd_can_get_f32(&f->data[4]);
        if (!isfinite(cmd->value)) {
            return HD_CAN_RES_NOT_FINITE;
        }
        return HD_CAN_RES_OK;
    case HD_CMD_SET_PARAM:
        cmd->value = hd_can_get_f32(&f->data[4]);
        if (!isfinite(cmd->value)) {
            return HD_CAN_RES_NOT_FINITE;
        }
        return HD_CAN_RES_OK;
    case HD_CMD_FILTER_ENABLE:
    case HD_CMD_BLOCK_ENABLE:
    case HD_CMD_BLOCKS_CLEAR:
    case HD_CMD_GET_PARAM:
    case HD_CMD_TARE:
    case HD_CMD_CALIB_SAVE:
    case HD_CMD_CALIB_LOAD:
    case HD_CMD_FILTER_RESET:
        return HD_CAN_RES_OK;
    default:
        return HD_CAN_RES_UNKNOWN_OPCODE;
    }
}

void hd_can_encode_ack(uint8_t node_id, const hd_can_ack_t *a, hal_can_frame_t *f)
{
    frame_init(f, HD_CAN_ID_ACK + node_id);
    f->data[0] = a->opcode;
    f->data[1] = a->token;
    f->data[2] = a->result;
    f->data[3] = a->aux;
    hd_can_put_f32(&f->data[4], a->value);
}

int hd_can_decode_ack(const hal_can_frame_t *f, hd_can_ack_t *out)
{
    if (f->len != HD_CAN_DLC || f->id < HD_CAN_ID_ACK || f->id > HD_CAN_ID_ACK + HD_CAN_NODE_MAX) {
        return -1;
    }
    out->opcode = f->data[0];
    out->token = f->data[1];
    out->result = f->data[2];
    out->aux = f->data[3];
    out->value = hd_can_get_f32(&f->data[4]);
    return 0;
}

const char *hd_can_result_str(int result)
{
    switch (result) {
    case HD_CAN_RES_OK: return "ok";
    case HD_CAN_RES_UNKNOWN_OPCODE: return "unknown opcode";
    case HD_CAN_RES_BAD_LENGTH: return "bad length";
    case HD_CAN_RES_BAD_FRAME: return "bad frame type";
    case HD_CAN_RES_OUT_OF_RANGE: return "out of range";
    case HD_CAN_RES_NOT_FINITE: return "not finite";
    case HD_CAN_RES_UNKNOWN_PARAM: return "unknown parameter";
    case HD_CAN_RES_READ_ONLY: return "read only";
    case HD_CAN_RES_NO_SPACE: return "no free filter block";
    case HD_CAN_RES_BAD_INDEX: return "no such filter block";
    case HD_CAN_RES_REJECTED: return "model rejected by the filter";
    case HD_CAN_RES_BUSY: return "busy";
    case HD_CAN_RES_NVM_ERROR: return "NVM error";
    case HD_CAN_RES_NO_DATA: return "no valid samples";
    default: return "unknown result";
    }
}

const char *hd_can_param_str(int param)
{
    switch (param) {
    case HD_PARAM_R_NM2: return "r_nm2";
    case HD_PARAM_GEAR_RATIO: return "gear_ratio";
    case HD_PARAM_INERTIA_KGM2: return "inertia_kgm2";
    case HD_PARAM_VISCOUS_NM_S_RAD: return "viscous_nm_s_rad";
    case HD_PARAM_COULOMB_NM: return "coulomb_nm";
    case HD_PARAM_OFFSET_ENABLED: return "offset";
    case HD_PARAM_OFFSET_Q_NM2: return "offset_q_nm2";
    case HD_PARAM_P0_NM2: return "p0_nm2";
    case HD_PARAM_TRACK_BANDWIDTH_HZ: return "track_bandwidth_hz";
    case HD_PARAM_TELEMETRY_RATE_HZ: return "telemetry_rate_hz";
    case HD_PARAM_NODE_ID: return "node_id";
    case HD_PARAM_CALIB_GAIN_NM_PER_V: return "calib_gain_nm_per_v";
    case HD_PARAM_CALIB_OFFSET_V: return "calib_offset_v";
    case HD_PARAM_BLOCK_COUNT: return "block_count";
    case HD_PARAM_FILTER_ENABLED: return "filter";
    default: return "unknown";
    }
}
