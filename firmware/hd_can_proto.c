/* hd_can_proto: see hd_can_proto.h.  The byte layouts are hd_protocol.def's
 * HD_SIGNAL / HD_ARG rows; hd_can_gen.c (generated) packs them.  What is
 * here knows no byte position: identifiers, checks, scaling rules and the
 * two frames whose meaning spans more than their bytes (a telemetry pair,
 * the angle without an output encoder). */
#include "hd_can_proto.h"

#include <math.h>   /* isfinite, NAN (compiler builtins, no libm call) */
#include <string.h>

#include "hd_record_store.h" /* record status codes */

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

int32_t hd_can_scale_int(float value, float lsb, int32_t max)
{
    if (!isfinite(value)) {
        return -max - 1;
    }
    float q = value / lsb;
    if (q >= (float)max) {
        return max;
    }
    if (q <= -(float)max) {
        return -max; /* -max - 1 is reserved for "not available" */
    }
    return (int32_t)(q >= 0.0f ? q + 0.5f : q - 0.5f);
}

uint32_t hd_can_scale_uq(float value, float mult, float max)
{
    float scaled = value * mult + 0.5f;
    return (scaled <= 0.0f) ? 0u : (scaled >= max ? (uint32_t)max : (uint32_t)scaled);
}

int16_t hd_can_scale_i16(float value, float lsb)
{
    return (int16_t)hd_can_scale_int(value, lsb, INT16_MAX);
}

int32_t hd_can_scale_i24(float value, float lsb)
{
    return hd_can_scale_int(value, lsb, HD_CAN_INT24_MAX);
}

/* Only the 8 bytes a classic frame carries are written: the tick encodes
 * several frames a millisecond, and the rest of data[] is never read. */
void hd_can_frame_init(hal_can_frame_t *f, hd_can_frame_type_t type, uint8_t node_id)
{
    memset(f->data, 0, HD_CAN_DLC);
    f->id = hd_can_id(type, node_id);
    f->flags = HAL_CAN_FLAG_EXT;
    f->len = HD_CAN_DLC;
}

bool hd_can_frame_is(const hal_can_frame_t *f, hd_can_frame_type_t type, uint8_t *node_id)
{
    uint8_t t = 0u;
    uint8_t n = 0u;
    if (!hd_can_id_parse(f->id, f->flags, &t, &n) || t != (uint8_t)type ||
        f->len != HD_CAN_DLC ||
        (f->flags & (HAL_CAN_FLAG_RTR | HAL_CAN_FLAG_ERR | HAL_CAN_FLAG_FD)) != 0u) {
        return false;
    }
    if (node_id != NULL) {
        *node_id = n;
    }
    return true;
}

int hd_can_rx_check(const hal_can_frame_t *f)
{
    if ((f->flags & (HAL_CAN_FLAG_RTR | HAL_CAN_FLAG_ERR | HAL_CAN_FLAG_FD)) != 0u) {
        return HD_CAN_RES_BAD_FRAME;
    }
    return f->len == HD_CAN_DLC ? HD_CAN_RES_OK : HD_CAN_RES_BAD_LENGTH;
}

void hd_can_encode_telem(uint8_t node_id, const hd_can_telem_t *t,
                         hal_can_frame_t *a, hal_can_frame_t *b)
{
    /* An invalid sample sends both torques as "not available" (NaN's code). */
    const hd_can_telem_a_t ta = {t->torque_valid ? t->torque_filtered_nm : NAN,
                                 t->torque_valid ? t->torque_raw_nm : NAN, t->ripple_nm, t->seq};
    const hd_can_telem_b_t tb = {t->motor_velocity_rad_s, t->faults, t->kf_status, t->seq};
    hd_can_encode_telem_a(node_id, &ta, a);
    hd_can_encode_telem_b(node_id, &tb, b);
}

int hd_can_decode_telem(const hal_can_frame_t *a, const hal_can_frame_t *b,
                        hd_can_telem_t *out)
{
    uint8_t na = 0u;
    uint8_t nb = 0u;
    hd_can_telem_a_t ta;
    hd_can_telem_b_t tb;
    if (!hd_can_frame_is(a, HD_CAN_FRAME_TELEM_A, &na) ||
        !hd_can_frame_is(b, HD_CAN_FRAME_TELEM_B, &nb) || na != nb) {
        return -1;
    }
    const uint32_t missing = hd_can_unpack_telem_a(a->data, &ta);
    (void)hd_can_unpack_telem_b(b->data, &tb);
    if (ta.seq != tb.seq) {
        return -1;
    }
    memset(out, 0, sizeof *out);
    out->torque_valid =
        (missing & (HD_CAN_NA_TELEM_A_TORQUE_FILTERED_NM | HD_CAN_NA_TELEM_A_TORQUE_RAW_NM)) == 0u;
    out->torque_filtered_nm = ta.torque_filtered_nm;
    out->torque_raw_nm = ta.torque_raw_nm;
    out->ripple_nm = ta.ripple_nm;
    out->seq = ta.seq;
    out->motor_velocity_rad_s = tb.motor_velocity_rad_s;
    out->faults = tb.faults;
    out->kf_status = tb.kf_status;
    return 0;
}

void hd_can_encode_angle(uint8_t node_id, const hd_can_angle_t *c, hal_can_frame_t *f)
{
    hd_can_angle_t sent = *c;
    if (!sent.has_output) {
        sent.output_counts = 0u;
    }
    hd_can_encode_telem_c(node_id, &sent, f);
}

int hd_can_decode_angle(const hal_can_frame_t *f, hd_can_angle_t *out)
{
    return hd_can_decode_telem_c(f, out);
}

int hd_can_decode_cmd(const hal_can_frame_t *f, hd_can_cmd_t *cmd)
{
    /* The header of a short frame, as far as it goes (the rest reads 0). */
    uint8_t data[HD_CAN_DLC] = {0};
    memcpy(data, f->data, f->len < HD_CAN_DLC ? f->len : HD_CAN_DLC);
    const uint32_t missing = hd_can_unpack_cmd(data, cmd);
    int rc = hd_can_rx_check(f);
    if (rc == HD_CAN_RES_OK && !hd_can_is_command(cmd->opcode)) {
        rc = HD_CAN_RES_UNKNOWN_OPCODE;
    }
    if (rc != HD_CAN_RES_OK) {
        memset(&cmd->arg, 0, sizeof cmd->arg);
        return rc;
    }
    return missing == 0u ? HD_CAN_RES_OK : HD_CAN_RES_NOT_FINITE;
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
