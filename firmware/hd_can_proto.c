/* hd_can_proto: see hd_can_proto.h.  Byte layouts: docs/protocol.md and
 * firmware/hdjoint.dbc (checked against this file by the tests). */
#include "hd_can_proto.h"

#include <math.h>   /* isfinite (a compiler builtin, no libm call) */
#include <string.h>

#include "hd_record_store.h" /* little-endian helpers, record status codes */

/* The record status codes travel on CAN as hd_record_status_t values. */
#define HD_RECORD_STATUS(code, NAME, doc) \
    _Static_assert((int)HD_RECORD_##NAME == (code), "record status " #NAME);
#include "hd_protocol.def"

uint32_t hd_can_id(hd_can_frame_type_t type, uint8_t node_id)
{
    return HD_CAN_ID_PREFIX | ((uint32_t)type << 8) | node_id;
}

bool hd_can_id_parse(uint32_t id, uint8_t flags, uint8_t *type, uint8_t *node_id)
{
    if ((flags & HAL_CAN_FLAG_EXT) == 0u || (id & HD_CAN_ID_PREFIX_MASK) != HD_CAN_ID_PREFIX) {
        return false;
    }
    uint8_t node = (uint8_t)(id & 0xFFu);
    if (node < HD_CAN_NODE_MIN || node > HD_CAN_NODE_MAX) {
        return false;
    }
    *type = (uint8_t)((id >> 8) & 0xFFu);
    *node_id = node;
    return true;
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

int32_t hd_can_scale_i24(float value, float lsb)
{
    if (!isfinite(value)) {
        return -HD_CAN_INT24_MAX - 1;
    }
    float q = value / lsb;
    if (q >= (float)HD_CAN_INT24_MAX) {
        return HD_CAN_INT24_MAX;
    }
    if (q <= -(float)HD_CAN_INT24_MAX) {
        return -HD_CAN_INT24_MAX;
    }
    return (int32_t)(q >= 0.0f ? q + 0.5f : q - 0.5f);
}

static void put_u24(uint8_t *p, uint32_t v)
{
    p[0] = (uint8_t)(v & 0xFFu);
    p[1] = (uint8_t)((v >> 8) & 0xFFu);
    p[2] = (uint8_t)((v >> 16) & 0xFFu);
}

static uint32_t get_u24(const uint8_t *p)
{
    return (uint32_t)p[0] | ((uint32_t)p[1] << 8) | ((uint32_t)p[2] << 16);
}

static int32_t get_i24(const uint8_t *p)
{
    uint32_t u = get_u24(p);
    return (u & 0x800000u) ? (int32_t)(u | 0xFF000000u) : (int32_t)u;
}

/* Only the 8 bytes a classic frame carries are written: the tick encodes
 * several frames a millisecond, and the rest of data[] is never read. */
static void frame_init(hal_can_frame_t *f, hd_can_frame_type_t type, uint8_t node_id)
{
    memset(f->data, 0, HD_CAN_DLC);
    f->id = hd_can_id(type, node_id);
    f->flags = HAL_CAN_FLAG_EXT;
    f->len = HD_CAN_DLC;
}

/* A frame of ours, of this type, 8 bytes, classic data frame. */
static bool frame_is(const hal_can_frame_t *f, hd_can_frame_type_t type, uint8_t *node)
{
    uint8_t t = 0u;
    uint8_t n = 0u;
    if (!hd_can_id_parse(f->id, f->flags, &t, &n) || t != (uint8_t)type ||
        f->len != HD_CAN_DLC ||
        (f->flags & (HAL_CAN_FLAG_RTR | HAL_CAN_FLAG_ERR | HAL_CAN_FLAG_FD)) != 0u) {
        return false;
    }
    if (node != NULL) {
        *node = n;
    }
    return true;
}

void hd_can_encode_telem(uint8_t node_id, const hd_can_telem_t *t,
                         hal_can_frame_t *a, hal_can_frame_t *b)
{
    frame_init(a, HD_CAN_FRAME_TELEM_A, node_id);
    int16_t filt = t->torque_valid ? hd_can_scale_i16(t->torque_filtered_nm, HD_CAN_TORQUE_LSB_NM)
                                   : HD_CAN_INT16_NA;
    int16_t raw = t->torque_valid ? hd_can_scale_i16(t->torque_raw_nm, HD_CAN_TORQUE_LSB_NM)
                                  : HD_CAN_INT16_NA;
    hd_le_put_u16(&a->data[0], (uint16_t)filt);
    hd_le_put_u16(&a->data[2], (uint16_t)raw);
    hd_le_put_u16(&a->data[4], (uint16_t)hd_can_scale_i16(t->ripple_nm, HD_CAN_RIPPLE_LSB_NM));
    a->data[6] = t->seq;
    a->data[7] = 0;

    frame_init(b, HD_CAN_FRAME_TELEM_B, node_id);
    put_u24(&b->data[0],
            (uint32_t)hd_can_scale_i24(t->motor_velocity_rad_s, HD_CAN_VELOCITY_LSB_RAD_S));
    put_u24(&b->data[3], t->faults & 0xFFFFFFu);
    b->data[6] = t->kf_status;
    b->data[7] = t->seq;
}

static float i16_to_float(uint16_t raw, float lsb)
{
    return (float)(int16_t)raw * lsb;
}

int hd_can_decode_telem(const hal_can_frame_t *a, const hal_can_frame_t *b,
                        hd_can_telem_t *out)
{
    uint8_t na = 0u;
    uint8_t nb = 0u;
    if (!frame_is(a, HD_CAN_FRAME_TELEM_A, &na) || !frame_is(b, HD_CAN_FRAME_TELEM_B, &nb) ||
        na != nb || a->data[6] != b->data[7]) {
        return -1;
    }
    memset(out, 0, sizeof *out);
    uint16_t filt = hd_le_get_u16(&a->data[0]);
    uint16_t raw = hd_le_get_u16(&a->data[2]);
    out->torque_valid = (int16_t)filt != HD_CAN_INT16_NA && (int16_t)raw != HD_CAN_INT16_NA;
    out->torque_filtered_nm = i16_to_float(filt, HD_CAN_TORQUE_LSB_NM);
    out->torque_raw_nm = i16_to_float(raw, HD_CAN_TORQUE_LSB_NM);
    out->ripple_nm = i16_to_float(hd_le_get_u16(&a->data[4]), HD_CAN_RIPPLE_LSB_NM);
    out->seq = a->data[6];
    out->motor_velocity_rad_s = (float)get_i24(&b->data[0]) * HD_CAN_VELOCITY_LSB_RAD_S;
    out->faults = get_u24(&b->data[3]);
    out->kf_status = b->data[6];
    return 0;
}

void hd_can_encode_angle(uint8_t node_id, const hd_can_angle_t *c, hal_can_frame_t *f)
{
    frame_init(f, HD_CAN_FRAME_TELEM_C, node_id);
    hd_le_put_u32(&f->data[0], c->motor_counts);
    uint32_t out = c->has_output ? ((c->output_counts & HD_CAN_OUTPUT_COUNTS_MASK) | 0x800000u) : 0u;
    put_u24(&f->data[4], out);
    f->data[7] = c->seq;
}

int hd_can_decode_angle(const hal_can_frame_t *f, hd_can_angle_t *out)
{
    if (!frame_is(f, HD_CAN_FRAME_TELEM_C, NULL)) {
        return -1;
    }
    out->motor_counts = hd_le_get_u32(&f->data[0]);
    uint32_t o = get_u24(&f->data[4]);
    out->has_output = (o & 0x800000u) != 0u;
    out->output_counts = o & HD_CAN_OUTPUT_COUNTS_MASK;
    out->seq = f->data[7];
    return 0;
}

void hd_can_encode_heartbeat(uint8_t node_id, const hd_can_heartbeat_t *h,
                             hal_can_frame_t *f)
{
    frame_init(f, HD_CAN_FRAME_HEARTBEAT, node_id);
    f->data[0] = h->state;
    put_u24(&f->data[1], h->faults & 0xFFFFFFu);
    hd_le_put_u16(&f->data[4], h->deadline_misses);
    f->data[6] = (uint8_t)((h->calib_status & 0x0Fu) | ((h->config_status & 0x0Fu) << 4));
    f->data[7] = h->profile_status;
}

int hd_can_decode_heartbeat(const hal_can_frame_t *f, hd_can_heartbeat_t *out)
{
    if (!frame_is(f, HD_CAN_FRAME_HEARTBEAT, NULL)) {
        return -1;
    }
    out->state = f->data[0];
    out->faults = get_u24(&f->data[1]);
    out->deadline_misses = hd_le_get_u16(&f->data[4]);
    out->calib_status = f->data[6] & 0x0Fu;
    out->config_status = (uint8_t)(f->data[6] >> 4);
    out->profile_status = f->data[7];
    return 0;
}

void hd_can_encode_boot(uint8_t node_id, const hd_can_boot_t *b, hal_can_frame_t *f)
{
    frame_init(f, HD_CAN_FRAME_BOOT, node_id);
    f->data[0] = b->reset_cause;
    f->data[1] = (uint8_t)((b->fault_valid ? 1u : 0u) | (b->config_from_record ? 2u : 0u));
    hd_le_put_u32(&f->data[2], b->fault_pc);
    f->data[6] = b->protocol_version;
    f->data[7] = b->config_status;
}

int hd_can_decode_boot(const hal_can_frame_t *f, hd_can_boot_t *out)
{
    if (!frame_is(f, HD_CAN_FRAME_BOOT, NULL)) {
        return -1;
    }
    out->reset_cause = f->data[0];
    out->fault_valid = (f->data[1] & 1u) != 0u;
    out->config_from_record = (f->data[1] & 2u) != 0u;
    out->fault_pc = hd_le_get_u32(&f->data[2]);
    out->protocol_version = f->data[6];
    out->config_status = f->data[7];
    return 0;
}

/* The checks every received frame of the tick gets before its bytes are read. */
static int rx_frame_check(const hal_can_frame_t *f)
{
    if ((f->flags & (HAL_CAN_FLAG_RTR | HAL_CAN_FLAG_ERR | HAL_CAN_FLAG_FD)) != 0u) {
        return HD_CAN_RES_BAD_FRAME;
    }
    return f->len == HD_CAN_DLC ? HD_CAN_RES_OK : HD_CAN_RES_BAD_LENGTH;
}

void hd_can_encode_feedforward(uint8_t node_id, const hd_can_feedforward_t *ff,
                               hal_can_frame_t *f)
{
    frame_init(f, HD_CAN_FRAME_FEEDFORWARD, node_id);
    hd_le_put_f32(&f->data[0], ff->torque_nm);
    f->data[4] = ff->seq;
}

int hd_can_decode_feedforward(const hal_can_frame_t *f, hd_can_feedforward_t *out)
{
    const int rc = rx_frame_check(f);
    if (rc != HD_CAN_RES_OK) {
        return rc;
    }
    float v = hd_le_get_f32(&f->data[0]);
    if (!isfinite(v)) {
        return HD_CAN_RES_NOT_FINITE;
    }
    out->torque_nm = v;
    out->seq = f->data[4];
    return HD_CAN_RES_OK;
}

void hd_can_encode_setpoint(uint8_t node_id, const hd_can_setpoint_t *sp, hal_can_frame_t *f)
{
    frame_init(f, HD_CAN_FRAME_SETPOINT, node_id);
    f->data[0] = sp->mode;
    f->data[1] = sp->seq;
    hd_le_put_u16(&f->data[2], (uint16_t)hd_can_scale_i16(sp->torque_nm, HD_CAN_SETPOINT_TORQUE_LSB_NM));
    hd_le_put_u16(&f->data[4],
                  (uint16_t)hd_can_scale_i16(sp->position_rad, HD_CAN_SETPOINT_POSITION_LSB_RAD));
    hd_le_put_u16(&f->data[6],
                  (uint16_t)hd_can_scale_i16(sp->velocity_rad_s, HD_CAN_SETPOINT_VELOCITY_LSB_RAD_S));
}

int hd_can_decode_setpoint(const hal_can_frame_t *f, hd_can_setpoint_t *out)
{
    const int rc = rx_frame_check(f);
    if (rc != HD_CAN_RES_OK) {
        return rc;
    }
    const uint16_t t = hd_le_get_u16(&f->data[2]);
    const uint16_t q = hd_le_get_u16(&f->data[4]);
    const uint16_t v = hd_le_get_u16(&f->data[6]);
    out->mode = f->data[0];
    out->seq = f->data[1];
    if ((int16_t)t == HD_CAN_INT16_NA || (int16_t)q == HD_CAN_INT16_NA ||
        (int16_t)v == HD_CAN_INT16_NA) {
        return HD_CAN_RES_NOT_FINITE;
    }
    out->torque_nm = i16_to_float(t, HD_CAN_SETPOINT_TORQUE_LSB_NM);
    out->position_rad = i16_to_float(q, HD_CAN_SETPOINT_POSITION_LSB_RAD);
    out->velocity_rad_s = i16_to_float(v, HD_CAN_SETPOINT_VELOCITY_LSB_RAD_S);
    return HD_CAN_RES_OK;
}

void hd_can_encode_gains(uint8_t node_id, const hd_can_gains_t *g, hal_can_frame_t *f)
{
    frame_init(f, HD_CAN_FRAME_GAINS, node_id);
    hd_le_put_f32(&f->data[0], g->kp_nm_rad);
    hd_le_put_f32(&f->data[4], g->kd_nm_s_rad);
}

int hd_can_decode_gains(const hal_can_frame_t *f, hd_can_gains_t *out)
{
    const int rc = rx_frame_check(f);
    if (rc != HD_CAN_RES_OK) {
        return rc;
    }
    const float kp = hd_le_get_f32(&f->data[0]);
    const float kd = hd_le_get_f32(&f->data[4]);
    if (!isfinite(kp) || !isfinite(kd)) {
        return HD_CAN_RES_NOT_FINITE;
    }
    out->kp_nm_rad = kp;
    out->kd_nm_s_rad = kd;
    return HD_CAN_RES_OK;
}

void hd_can_encode_ctrl_state(uint8_t node_id, const hd_can_ctrl_state_t *c, hal_can_frame_t *f)
{
    frame_init(f, HD_CAN_FRAME_CTRL_STATE, node_id);
    f->data[0] = (uint8_t)((c->mode_asked & 0x0Fu) | (uint8_t)(c->mode_run << 4));
    f->data[1] = c->limits;
    hd_le_put_u16(&f->data[2], (uint16_t)hd_can_scale_i16(c->torque_ref_nm, HD_CAN_CTRL_TORQUE_LSB_NM));
    hd_le_put_u16(&f->data[4], (uint16_t)hd_can_scale_i16(c->current_a, HD_CAN_CTRL_CURRENT_LSB_A));
    f->data[6] = c->seq;
    f->data[7] = c->flags;
}

int hd_can_decode_ctrl_state(const hal_can_frame_t *f, hd_can_ctrl_state_t *out)
{
    if (!frame_is(f, HD_CAN_FRAME_CTRL_STATE, NULL)) {
        return -1;
    }
    out->mode_asked = f->data[0] & 0x0Fu;
    out->mode_run = (uint8_t)(f->data[0] >> 4);
    out->limits = f->data[1];
    out->torque_ref_nm = i16_to_float(hd_le_get_u16(&f->data[2]), HD_CAN_CTRL_TORQUE_LSB_NM);
    out->current_a = i16_to_float(hd_le_get_u16(&f->data[4]), HD_CAN_CTRL_CURRENT_LSB_A);
    out->seq = f->data[6];
    out->flags = f->data[7];
    return 0;
}

static bool is_add_opcode(uint8_t op)
{
    return op == HD_CMD_ADD_MOTOR || op == HD_CMD_ADD_OUTPUT || op == HD_CMD_ADD_FIXED;
}

void hd_can_encode_cmd(uint8_t node_id, const hd_can_cmd_t *c, hal_can_frame_t *f)
{
    frame_init(f, HD_CAN_FRAME_CMD, node_id);
    f->data[0] = c->opcode;
    f->data[1] = c->token;
    if (is_add_opcode(c->opcode)) {
        float scaled = c->order * 100.0f + 0.5f;
        uint16_t u = (scaled <= 0.0f) ? 0u : (scaled >= 65535.0f ? 65535u : (uint16_t)scaled);
        hd_le_put_u16(&f->data[2], u);
        hd_le_put_f32(&f->data[4], c->value);
    } else if (c->opcode == HD_CMD_CALIB_SAVE) {
        hd_le_put_u32(&f->data[4], c->arg_u32);
    } else {
        f->data[2] = c->arg_u8[0];
        f->data[3] = c->arg_u8[1];
        hd_le_put_f32(&f->data[4], c->value);
    }
}

static bool opcode_known(uint8_t op)
{
    if (op == HD_CMD_SETPOINT_REFUSED) {
        return false; /* an ACK's opcode only: no command */
    }
    switch (op) {
#define HD_OPCODE(code, NAME, doc) case code:
#include "hd_protocol.def"
        return true;
    default:
        return false;
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
    if ((f->flags & (HAL_CAN_FLAG_RTR | HAL_CAN_FLAG_ERR | HAL_CAN_FLAG_FD)) != 0u) {
        return HD_CAN_RES_BAD_FRAME;
    }
    if (f->len != HD_CAN_DLC) {
        return HD_CAN_RES_BAD_LENGTH;
    }
    if (!opcode_known(cmd->opcode)) {
        return HD_CAN_RES_UNKNOWN_OPCODE;
    }
    cmd->arg_u8[0] = f->data[2];
    cmd->arg_u8[1] = f->data[3];
    cmd->arg_u32 = hd_le_get_u32(&f->data[4]);
    if (is_add_opcode(cmd->opcode)) {
        cmd->order = (float)hd_le_get_u16(&f->data[2]) / 100.0f;
    }
    if (is_add_opcode(cmd->opcode) || cmd->opcode == HD_CMD_SET_PARAM) {
        cmd->value = hd_le_get_f32(&f->data[4]);
        if (!isfinite(cmd->value)) {
            return HD_CAN_RES_NOT_FINITE;
        }
    }
    return HD_CAN_RES_OK;
}

bool hd_can_ack_is_u32(uint8_t opcode)
{
    return opcode == HD_CMD_VERSION || opcode == HD_CMD_INFO;
}

void hd_can_encode_ack(uint8_t node_id, const hd_can_ack_t *a, hal_can_frame_t *f)
{
    frame_init(f, HD_CAN_FRAME_ACK, node_id);
    f->data[0] = a->opcode;
    f->data[1] = a->token;
    f->data[2] = a->result;
    f->data[3] = a->aux;
    if (hd_can_ack_is_u32(a->opcode)) {
        hd_le_put_u32(&f->data[4], a->value_u32);
    } else {
        hd_le_put_f32(&f->data[4], a->value);
    }
}

int hd_can_decode_ack(const hal_can_frame_t *f, hd_can_ack_t *out)
{
    if (!frame_is(f, HD_CAN_FRAME_ACK, NULL)) {
        return -1;
    }
    memset(out, 0, sizeof *out);
    out->opcode = f->data[0];
    out->token = f->data[1];
    out->result = f->data[2];
    out->aux = f->data[3];
    if (hd_can_ack_is_u32(out->opcode)) {
        out->value_u32 = hd_le_get_u32(&f->data[4]);
    } else {
        out->value = hd_le_get_f32(&f->data[4]);
    }
    return 0;
}

const char *hd_can_result_str(int result)
{
    switch (result) {
#define HD_RESULT(code, NAME, doc) case code: return #NAME;
#include "hd_protocol.def"
    default: return "UNKNOWN_RESULT";
    }
}

const char *hd_can_opcode_str(int opcode)
{
    switch (opcode) {
#define HD_OPCODE(code, NAME, doc) case code: return #NAME;
#include "hd_protocol.def"
    default: return "UNKNOWN_OPCODE";
    }
}

const char *hd_can_fault_str(unsigned bit)
{
    switch (bit) {
#define HD_FAULT(b, NAME, doc) case b: return #NAME;
#include "hd_protocol.def"
    default: return "UNKNOWN_FAULT";
    }
}
