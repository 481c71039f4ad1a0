/*
 * hd_can_proto: the joint's CAN protocol as pure encode/decode functions.
 *
 * Classic CAN, 29-bit identifiers, every frame 8 bytes, little-endian:
 *   identifier = HD_CAN_ID_PREFIX | frame type << 8 | node_id (1..127).
 * 29-bit identifiers keep the protocol out of CANopen's 11-bit predefined
 * connection set (docs/reference/protocol.md, "Sharing a bus").  Frame types, their
 * signals, opcodes with their arguments and replies, results, fault bits and
 * states are the rows of hd_protocol.def; the structs and pack / unpack code
 * are generated from them (hd_can_gen.h), and so is firmware/hdjoint.dbc.
 *
 * Pure: no I/O, no heap, no globals; the decoders check everything and
 * never trust a length or a float from the bus.
 */
#ifndef HD_CAN_PROTO_H
#define HD_CAN_PROTO_H

#include <stdbool.h>
#include <stdint.h>

#include "hal.h"

#ifdef __cplusplus
extern "C" {
#endif

#define HD_CAN_PROTOCOL_VERSION 2u
#define HD_CAN_ID_PREFIX 0x01D00000u
#define HD_CAN_ID_PREFIX_MASK 0x1FFF0000u

#define HD_CAN_NODE_MIN 1u
#define HD_CAN_NODE_MAX 127u
#define HD_CAN_DLC 8u

typedef enum {
#define HD_FRAME(type, NAME, dir, dlc, doc) HD_CAN_FRAME_##NAME = type,
#include "hd_protocol.def"
} hd_can_frame_type_t;

typedef enum {
#define HD_OPCODE(code, NAME, doc) HD_CMD_##NAME = code,
#include "hd_protocol.def"
} hd_can_opcode_t;

typedef enum {
#define HD_RESULT(code, NAME, doc) HD_CAN_RES_##NAME = code,
#include "hd_protocol.def"
} hd_can_result_t;

enum {
#define HD_FAULT(bit, NAME, doc) HD_FAULT_##NAME = 1u << (bit),
#include "hd_protocol.def"
};
enum {
#define HD_FAULT(bit, NAME, doc) HD_FAULT_BIT_##NAME = bit,
#include "hd_protocol.def"
    HD_FAULT_BIT_END_
};
#define HD_FAULT_COUNT ((unsigned)HD_FAULT_BIT_END_)

typedef enum {
#define HD_STATE(code, NAME, doc) HD_STATE_##NAME = code,
#include "hd_protocol.def"
} hd_fw_state_t;

typedef enum {
#define HD_INFO_ITEM(code, NAME, doc) HD_INFO_##NAME = code,
#include "hd_protocol.def"
} hd_can_info_item_t;

typedef enum {
#define HD_BLOCK_FIELD(code, NAME, doc) HD_BLOCK_FIELD_##NAME = code,
#include "hd_protocol.def"
} hd_can_block_field_t;

/* A scaled signed signal (HD_SIGNAL type I) saturates at +-(2^(bits-1) - 1);
 * -2^(bits-1) is "not available". */
#define HD_CAN_INT24_MAX 8388607

/* CTRL_STATE's flags (CtrlFlags) */
#define HD_CAN_CTRL_FLAG_ENABLED  0x01u  /* the drive is told to drive */
#define HD_CAN_CTRL_FLAG_WATCHDOG 0x02u  /* the setpoint stream timed out */
#define HD_CAN_CTRL_FLAG_LATCHED  0x04u  /* STOP latched (encoder lost, drive fault) */
#define HD_CAN_CTRL_FLAG_NO_DRIVE 0x08u  /* the board has no drive */

/* Identifier of a frame type for a node, and the reverse: true if id is one
 * of ours (29-bit, our prefix, node in range). */
uint32_t hd_can_id(hd_can_frame_type_t type, uint8_t node_id);
bool hd_can_id_parse(uint32_t id, uint8_t flags, uint8_t *type, uint8_t *node_id);

/* value / lsb rounded half away from zero to an integer within +-max
 * (saturating); NaN and infinities give -max - 1, "not available". */
int32_t hd_can_scale_int(float value, float lsb, int32_t max);
/* value x mult rounded to an unsigned integer within 0 .. max. */
uint32_t hd_can_scale_uq(float value, float mult, float max);
/* The same for int16 and int24 signals. */
int16_t hd_can_scale_i16(float value, float lsb);
int32_t hd_can_scale_i24(float value, float lsb);

/* What the generated codec (hd_can_gen.c) builds on: a frame of this type for
 * the node, 8 zero bytes; is f this type of a node of ours, 8 bytes, classic
 * data frame (node may be NULL); the checks every received frame gets before
 * its bytes are read (HD_CAN_RES_OK, BAD_FRAME, BAD_LENGTH). */
void hd_can_frame_init(hal_can_frame_t *f, hd_can_frame_type_t type, uint8_t node_id);
bool hd_can_frame_is(const hal_can_frame_t *f, hd_can_frame_type_t type, uint8_t *node_id);
int hd_can_rx_check(const hal_can_frame_t *f);

/* The frames' and commands' structs and codecs, generated from hd_protocol.def. */
#include "hd_can_gen.h"

/* One telemetry sample: TELEM_A and TELEM_B of the same sequence. */
typedef struct {
    float torque_filtered_nm;
    float torque_raw_nm;
    float ripple_nm;
    bool torque_valid;         /* false: both torques sent as "not available" */
    float motor_velocity_rad_s;
    uint32_t faults;           /* HD_FAULT_* since the previous telemetry frame (24 bits) */
    uint8_t kf_status;         /* HD_KF_STATUS_* since the previous telemetry frame */
    uint8_t seq;
} hd_can_telem_t;

void hd_can_encode_telem(uint8_t node_id, const hd_can_telem_t *t,
                         hal_can_frame_t *a, hal_can_frame_t *b);
/* Decodes a TELEM_A / TELEM_B pair of one node; returns 0 or -1 if the ids
 * or lengths do not match or the sequence numbers differ. */
int hd_can_decode_telem(const hal_can_frame_t *a, const hal_can_frame_t *b,
                        hd_can_telem_t *out);

/* TELEM_C: without an output encoder (has_output false) its count is sent as 0. */
typedef hd_can_telem_c_t hd_can_angle_t;
void hd_can_encode_angle(uint8_t node_id, const hd_can_angle_t *c, hal_can_frame_t *f);
int hd_can_decode_angle(const hal_can_frame_t *f, hd_can_angle_t *out);

/* Checks a received command frame (id already matched) and decodes it.
 * Returns HD_CAN_RES_OK or the error to put in the ACK; cmd->opcode and
 * cmd->token are filled whenever the frame has them, so the error ACK can
 * echo them; the arguments only on HD_CAN_RES_OK. */
int hd_can_decode_cmd(const hal_can_frame_t *f, hd_can_cmd_t *cmd);

/* Static names for logs and tests (the NAME column of hd_protocol.def). */
const char *hd_can_result_str(int result);
const char *hd_can_opcode_str(int opcode);
const char *hd_can_fault_str(unsigned bit);

#ifdef __cplusplus
}
#endif

#endif /* HD_CAN_PROTO_H */
