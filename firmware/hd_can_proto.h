/*
 * hd_can_proto: the joint's CAN protocol as pure encode/decode functions.
 *
 * Classic CAN, 29-bit identifiers, every frame 8 bytes, little-endian:
 *   identifier = HD_CAN_ID_PREFIX | frame type << 8 | node_id (1..127).
 * 29-bit identifiers keep the protocol out of CANopen's 11-bit predefined
 * connection set (docs/protocol.md, "Sharing a bus").  Frame types, opcodes,
 * results, fault bits and states are the rows of hd_protocol.def;
 * firmware/hdjoint.dbc describes the byte layouts for node 1 and a test
 * checks it against this code.
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

/* Telemetry scaling (int16 fields saturate; -32768 means "not available"). */
#define HD_CAN_TORQUE_LSB_NM 0.01f
#define HD_CAN_RIPPLE_LSB_NM 0.001f
#define HD_CAN_VELOCITY_LSB_RAD_S 0.001f   /* int24: +-8388 rad/s */
#define HD_CAN_INT16_NA INT16_MIN
#define HD_CAN_INT24_MAX 8388607
#define HD_CAN_OUTPUT_COUNTS_MASK 0x7FFFFFu /* TELEM_C: low 23 bits, bit 23 = present */

/* Control frames (issue 23; docs/protocol.md, "Control"). */
#define HD_CAN_SETPOINT_TORQUE_LSB_NM 0.002f      /* int16: +-65.5 N m */
#define HD_CAN_SETPOINT_POSITION_LSB_RAD 0.001f   /* int16: +-32.767 rad */
#define HD_CAN_SETPOINT_VELOCITY_LSB_RAD_S 0.001f /* int16: +-32.767 rad/s */
#define HD_CAN_CTRL_TORQUE_LSB_NM 0.01f
#define HD_CAN_CTRL_CURRENT_LSB_A 0.001f
/* CTRL_STATE byte 7 */
#define HD_CAN_CTRL_FLAG_ENABLED  0x01u  /* the drive is told to drive */
#define HD_CAN_CTRL_FLAG_WATCHDOG 0x02u  /* the setpoint stream timed out */
#define HD_CAN_CTRL_FLAG_LATCHED  0x04u  /* STOP latched (encoder lost, drive fault) */
#define HD_CAN_CTRL_FLAG_NO_DRIVE 0x08u  /* the board has no drive */

/* Identifier of a frame type for a node, and the reverse: true if id is one
 * of ours (29-bit, our prefix, node in range). */
uint32_t hd_can_id(hd_can_frame_type_t type, uint8_t node_id);
bool hd_can_id_parse(uint32_t id, uint8_t flags, uint8_t *type, uint8_t *node_id);

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

typedef struct {
    uint32_t motor_counts;     /* the encoder's free-running count */
    uint32_t output_counts;    /* low 23 bits on the bus */
    bool has_output;
    uint8_t seq;               /* equal to the TELEM_A/B pair of the same tick */
} hd_can_angle_t;

typedef struct {
    uint8_t state;            /* hd_fw_state_t */
    uint32_t faults;          /* HD_FAULT_* since the previous heartbeat (24 bits) */
    uint16_t deadline_misses; /* total, saturating */
    uint8_t calib_status;     /* hd_record_status_t, 0..15 */
    uint8_t config_status;    /* hd_record_status_t, 0..15 */
    uint8_t profile_status;   /* hd_record_status_t */
} hd_can_heartbeat_t;

typedef struct {
    uint8_t reset_cause;      /* HAL_RESET_* */
    bool fault_valid;         /* a HardFault record survived */
    bool config_from_record;  /* booted from the saved configuration */
    uint32_t fault_pc;
    uint8_t protocol_version;
    uint8_t config_status;    /* hd_record_status_t */
} hd_can_boot_t;

typedef struct {
    float torque_nm;          /* the controller's expected torque */
    uint8_t seq;              /* free-running; repeated values are not new data */
} hd_can_feedforward_t;

/* SETPOINT: u8 mode, u8 seq, i16 torque, i16 position, i16 velocity.  The
 * int16 value -32768 is "not a number": such a frame is refused. */
typedef struct {
    uint8_t mode;             /* hd_ctrl_mode_t; others are refused */
    uint8_t seq;              /* free-running; a repeated value is stale, not new */
    float torque_nm;
    float position_rad;
    float velocity_rad_s;
} hd_can_setpoint_t;

/* GAINS: f32 kp (N m/rad), f32 kd (N m s/rad). */
typedef struct {
    float kp_nm_rad;
    float kd_nm_s_rad;
} hd_can_gains_t;

/* CTRL_STATE: u8 mode asked | mode run << 4, u8 limits (HD_CTRL_LIM_*),
 * i16 torque reference (0.01 N m), i16 current command (1 mA), u8 the last
 * setpoint's seq, u8 flags (HD_CAN_CTRL_FLAG_*). */
typedef struct {
    uint8_t mode_asked;
    uint8_t mode_run;
    uint8_t limits;
    float torque_ref_nm;
    float current_a;
    uint8_t seq;
    uint8_t flags;
} hd_can_ctrl_state_t;

typedef struct {
    uint8_t opcode;
    uint8_t token;    /* any value; echoed in the ACK so a host can match replies */
    uint8_t arg_u8[2]; /* bytes 2 and 3 */
    float order;      /* ADD_*: bytes 2..3 as u16 / 100 */
    float value;      /* SET_PARAM value / ADD_* q_nm2: bytes 4..7 as f32 */
    uint32_t arg_u32; /* CALIB_SAVE: bytes 4..7 as u32 */
} hd_can_cmd_t;

typedef struct {
    uint8_t opcode;
    uint8_t token;
    uint8_t result;   /* hd_can_result_t */
    uint8_t aux;      /* param id, block index, info item, record status ... */
    float value;      /* param value, tare offset, ... (f32) */
    uint32_t value_u32; /* VERSION / INFO: bytes 4..7 as u32 instead of value */
} hd_can_ack_t;

/* Rounds value/lsb to the nearest int16, saturating at +-32767 (NaN -> NA). */
int16_t hd_can_scale_i16(float value, float lsb);
/* Same for int24 (+-8388607; NaN -> -8388608). */
int32_t hd_can_scale_i24(float value, float lsb);

void hd_can_encode_telem(uint8_t node_id, const hd_can_telem_t *t,
                         hal_can_frame_t *a, hal_can_frame_t *b);
/* Decodes a TELEM_A / TELEM_B pair of one node; returns 0 or -1 if the ids
 * or lengths do not match or the sequence numbers differ. */
int hd_can_decode_telem(const hal_can_frame_t *a, const hal_can_frame_t *b,
                        hd_can_telem_t *out);
void hd_can_encode_angle(uint8_t node_id, const hd_can_angle_t *c, hal_can_frame_t *f);
int hd_can_decode_angle(const hal_can_frame_t *f, hd_can_angle_t *out);

void hd_can_encode_heartbeat(uint8_t node_id, const hd_can_heartbeat_t *h,
                             hal_can_frame_t *f);
int hd_can_decode_heartbeat(const hal_can_frame_t *f, hd_can_heartbeat_t *out);
void hd_can_encode_boot(uint8_t node_id, const hd_can_boot_t *b, hal_can_frame_t *f);
int hd_can_decode_boot(const hal_can_frame_t *f, hd_can_boot_t *out);

void hd_can_encode_feedforward(uint8_t node_id, const hd_can_feedforward_t *ff,
                               hal_can_frame_t *f);
/* Returns HD_CAN_RES_OK, HD_CAN_RES_BAD_FRAME / BAD_LENGTH, or
 * HD_CAN_RES_NOT_FINITE (the value is never trusted). */
int hd_can_decode_feedforward(const hal_can_frame_t *f, hd_can_feedforward_t *out);

void hd_can_encode_setpoint(uint8_t node_id, const hd_can_setpoint_t *sp, hal_can_frame_t *f);
/* HD_CAN_RES_OK, BAD_FRAME / BAD_LENGTH, or NOT_FINITE (an int16 at -32768).
 * The mode and the ranges are the firmware's to check. */
int hd_can_decode_setpoint(const hal_can_frame_t *f, hd_can_setpoint_t *out);
void hd_can_encode_gains(uint8_t node_id, const hd_can_gains_t *g, hal_can_frame_t *f);
/* HD_CAN_RES_OK, BAD_FRAME / BAD_LENGTH, or NOT_FINITE. */
int hd_can_decode_gains(const hal_can_frame_t *f, hd_can_gains_t *out);
void hd_can_encode_ctrl_state(uint8_t node_id, const hd_can_ctrl_state_t *c, hal_can_frame_t *f);
int hd_can_decode_ctrl_state(const hal_can_frame_t *f, hd_can_ctrl_state_t *out);

void hd_can_encode_cmd(uint8_t node_id, const hd_can_cmd_t *c, hal_can_frame_t *f);
/* Checks a received command frame (id already matched) and decodes it.
 * Returns HD_CAN_RES_OK or the error to put in the ACK; cmd->opcode and
 * cmd->token are filled whenever the frame has them, so the error ACK can
 * echo them. */
int hd_can_decode_cmd(const hal_can_frame_t *f, hd_can_cmd_t *cmd);

void hd_can_encode_ack(uint8_t node_id, const hd_can_ack_t *a, hal_can_frame_t *f);
int hd_can_decode_ack(const hal_can_frame_t *f, hd_can_ack_t *out);
/* Opcodes whose ACK carries a u32 (value_u32) instead of a float. */
bool hd_can_ack_is_u32(uint8_t opcode);

/* Static names for logs and tests (the NAME column of hd_protocol.def). */
const char *hd_can_result_str(int result);
const char *hd_can_opcode_str(int opcode);
const char *hd_can_fault_str(unsigned bit);

#ifdef __cplusplus
}
#endif

#endif /* HD_CAN_PROTO_H */
