/*
 * hd_can_proto: the joint's CAN protocol, as pure encode/decode functions.
 *
 * Classic CAN, 11-bit identifiers, every frame 8 bytes, little-endian,
 * identifier = base + node_id (node_id 1..127).  firmware/hdjoint.dbc
 * describes the same layout for node 1; docs/firmware.md has the tables.
 *
 *   base    name       dir  rate                     content
 *   0x100   TELEM_A    tx   telemetry rate (<= 1 kHz) filtered, raw torque, ripple, seq
 *   0x180   TELEM_B    tx   telemetry rate           motor velocity, faults, kf status, seq
 *   0x580   ACK        tx   one per command          opcode, token, result, aux, value
 *   0x600   CMD        rx   -                        opcode, token, arguments
 *   0x700   HEARTBEAT  tx   1 Hz                     state, faults, counters, calib status
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

#define HD_CAN_ID_TELEM_A   0x100u
#define HD_CAN_ID_TELEM_B   0x180u
#define HD_CAN_ID_ACK       0x580u
#define HD_CAN_ID_CMD       0x600u
#define HD_CAN_ID_HEARTBEAT 0x700u

#define HD_CAN_NODE_MIN 1u
#define HD_CAN_NODE_MAX 127u
#define HD_CAN_DLC 8u

/* Telemetry scaling (int16 fields saturate; -32768 means "not available"). */
#define HD_CAN_TORQUE_LSB_NM 0.01f
#define HD_CAN_RIPPLE_LSB_NM 0.001f
#define HD_CAN_VELOCITY_LSB_RAD_S 0.001f
#define HD_CAN_INT16_NA INT16_MIN

/* Command opcodes (CMD byte 0, echoed in ACK byte 0). */
typedef enum {
    HD_CMD_FILTER_ENABLE = 0x01, /* u8 enable at byte 2 */
    HD_CMD_ADD_MOTOR = 0x10,     /* u16 order*100 at 2..3, f32 q_nm2 at 4..7 */
    HD_CMD_ADD_OUTPUT = 0x11,    /* same layout */
    HD_CMD_ADD_FIXED = 0x12,     /* u16 frequency_hz*100 at 2..3, f32 q_nm2 at 4..7 */
    HD_CMD_BLOCK_ENABLE = 0x13,  /* u8 block index at 2, u8 enable at 3 */
    HD_CMD_BLOCKS_CLEAR = 0x14,  /* no arguments */
    HD_CMD_SET_PARAM = 0x20,     /* u8 param id at 2, f32 value at 4..7 */
    HD_CMD_GET_PARAM = 0x21,     /* u8 param id at 2 */
    HD_CMD_TARE = 0x30,          /* no arguments: offset_v := mean bridge volts */
    HD_CMD_CALIB_SAVE = 0x31,    /* u32 calibrated_unix_s at 4..7 */
    HD_CMD_CALIB_LOAD = 0x32,    /* no arguments */
    HD_CMD_FILTER_RESET = 0x40,  /* no arguments */
} hd_can_opcode_t;

/* Parameter ids for SET_PARAM / GET_PARAM (value always f32). */
typedef enum {
    HD_PARAM_R_NM2 = 1,
    HD_PARAM_GEAR_RATIO = 2,
    HD_PARAM_INERTIA_KGM2 = 3,
    HD_PARAM_VISCOUS_NM_S_RAD = 4,
    HD_PARAM_COULOMB_NM = 5,
    HD_PARAM_OFFSET_ENABLED = 6,   /* 0 or 1 */
    HD_PARAM_OFFSET_Q_NM2 = 7,
    HD_PARAM_P0_NM2 = 8,
    HD_PARAM_TRACK_BANDWIDTH_HZ = 9,
    HD_PARAM_TELEMETRY_RATE_HZ = 10, /* integer 0..1000; 0 = off */
    HD_PARAM_NODE_ID = 11,           /* integer 1..127; ACK sent from the old id */
    HD_PARAM_CALIB_GAIN_NM_PER_V = 12,
    HD_PARAM_CALIB_OFFSET_V = 13,
    HD_PARAM_BLOCK_COUNT = 14,       /* read only */
    HD_PARAM_FILTER_ENABLED = 15,    /* 0 or 1 */
    HD_PARAM_COUNT_ = 16
} hd_can_param_t;

/* ACK result codes (ACK byte 2). */
typedef enum {
    HD_CAN_RES_OK = 0,
    HD_CAN_RES_UNKNOWN_OPCODE = 1,
    HD_CAN_RES_BAD_LENGTH = 2,     /* DLC != 8 */
    HD_CAN_RES_BAD_FRAME = 3,      /* RTR, extended id, FD or error frame on the command id */
    HD_CAN_RES_OUT_OF_RANGE = 4,   /* value outside its documented range */
    HD_CAN_RES_NOT_FINITE = 5,     /* NaN or infinity */
    HD_CAN_RES_UNKNOWN_PARAM = 6,
    HD_CAN_RES_READ_ONLY = 7,
    HD_CAN_RES_NO_SPACE = 8,       /* no free filter block */
    HD_CAN_RES_BAD_INDEX = 9,      /* no such filter block */
    HD_CAN_RES_REJECTED = 10,      /* the filter refused the resulting model */
    HD_CAN_RES_BUSY = 11,          /* an NVM operation is already pending */
    HD_CAN_RES_NVM_ERROR = 12,
    HD_CAN_RES_NO_DATA = 13,       /* tare without valid samples */
} hd_can_result_t;

/* Fault / status bits (TELEM_B faults, HEARTBEAT faults). */
#define HD_FAULT_ADC_ERROR      (1u << 0)  /* ADC read failed or sample not finite */
#define HD_FAULT_ADC_SATURATED  (1u << 1)
#define HD_FAULT_OPEN_BRIDGE    (1u << 2)  /* ADC reported a fault (open bridge) */
#define HD_FAULT_TORQUE_RANGE   (1u << 3)  /* |torque| above torque_limit_nm */
#define HD_FAULT_ENC_GLITCH     (1u << 4)  /* impossible count jump: delta replaced */
#define HD_FAULT_ENC_FAULT      (1u << 5)  /* encoder reported a fault / read failed */
#define HD_FAULT_KF_FROZEN      (1u << 6)  /* a block is over Nyquist (frozen) */
#define HD_FAULT_KF_RESET       (1u << 7)  /* the filter reset itself (non-finite state) */
#define HD_FAULT_CAN_TX_FULL    (1u << 8)
#define HD_FAULT_CAN_BUS_OFF    (1u << 9)
#define HD_FAULT_CALIB_MISSING  (1u << 10) /* no record: defaults in use */
#define HD_FAULT_CALIB_CORRUPT  (1u << 11) /* corrupt / bad version / I/O: defaults in use */
#define HD_FAULT_DEADLINE_MISS  (1u << 12)
#define HD_FAULT_CMD_ERROR      (1u << 13) /* a command was rejected */
#define HD_FAULT_CALIB_ONE_COPY (1u << 14) /* record ok, but one stored copy was bad */
#define HD_FAULT_COUNT 15u

/* Heartbeat state. */
typedef enum {
    HD_STATE_INIT = 0,
    HD_STATE_RUN = 1,
    HD_STATE_DEGRADED = 2, /* running with a fault active since the last heartbeat */
    HD_STATE_STOPPED = 3,  /* sample source ended */
} hd_fw_state_t;

typedef struct {
    float torque_filtered_nm;
    float torque_raw_nm;
    float ripple_nm;
    bool torque_valid;         /* false: both torques sent as "not available" */
    float motor_velocity_rad_s;
    uint16_t faults;           /* HD_FAULT_* since the previous telemetry frame */
    uint8_t kf_status;         /* HD_KF_STATUS_* since the previous telemetry frame */
    uint8_t seq;
} hd_can_telem_t;

typedef struct {
    uint8_t state;            /* hd_fw_state_t */
    uint16_t faults;          /* HD_FAULT_* since the previous heartbeat */
    uint16_t deadline_misses; /* total, saturating */
    uint16_t fault_ticks;     /* total ticks with any fault, saturating */
    uint8_t calib_status;     /* 0 ok, 1 one copy bad, 2 missing, 3 corrupt, 4 bad version, 5 I/O */
} hd_can_heartbeat_t;

typedef struct {
    uint8_t opcode;
    uint8_t token;   /* any value; echoed in the ACK so a host can match replies */
    uint8_t arg_u8[2]; /* bytes 2 and 3 */
    float order;     /* ADD_*: bytes 2..3 as u16 / 100 */
    float value;     /* SET_PARAM value / ADD_* q_nm2: bytes 4..7 as f32 */
    uint32_t arg_u32; /* CALIB_SAVE: bytes 4..7 as u32 */
} hd_can_cmd_t;

typedef struct {
    uint8_t opcode;
    uint8_t token;
    uint8_t result; /* hd_can_result_t */
    uint8_t aux;    /* param id, block index, ... */
    float value;    /* param value, tare offset, ... */
} hd_can_ack_t;

/* Little-endian helpers (exposed for the tests and other frames). */
void hd_can_put_u16(uint8_t *p, uint16_t v);
void hd_can_put_u32(uint8_t *p, uint32_t v);
void hd_can_put_f32(uint8_t *p, float v);
uint16_t hd_can_get_u16(const uint8_t *p);
uint32_t hd_can_get_u32(const uint8_t *p);
float hd_can_get_f32(const uint8_t *p);

/* Rounds value/lsb to the nearest int16, saturating at +-32767 (NaN -> NA). */
int16_t hd_can_scale_i16(float value, float lsb);
/* Same for int32 (+-2^31-1). */
int32_t hd_can_scale_i32(float value, float lsb);

void hd_can_encode_telem(uint8_t node_id, const hd_can_telem_t *t,
                         hal_can_frame_t *a, hal_can_frame_t *b);
/* Decodes a TELEM_A / TELEM_B pair (any node); returns 0 or -1 if the ids or
 * lengths do not match or the sequence numbers differ. */
int hd_can_decode_telem(const hal_can_frame_t *a, const hal_can_frame_t *b,
                        hd_can_telem_t *out);

void hd_can_encode_heartbeat(uint8_t node_id, const hd_can_heartbeat_t *h,
                             hal_can_frame_t *f);
int hd_can_decode_heartbeat(const hal_can_frame_t *f, hd_can_heartbeat_t *out);

void hd_can_encode_cmd(uint8_t node_id, const hd_can_cmd_t *c, hal_can_frame_t *f);
/* Checks a received command frame (id already matched) and decodes it.
 * Returns HD_CAN_RES_OK or the error to put in the ACK; cmd->opcode and
 * cmd->token are filled whenever the frame has them, so the error ACK can
 * echo them. */
int hd_can_decode_cmd(const hal_can_frame_t *f, hd_can_cmd_t *cmd);

void hd_can_encode_ack(uint8_t node_id, const hd_can_ack_t *a, hal_can_frame_t *f);
int hd_can_decode_ack(const hal_can_frame_t *f, hd_can_ack_t *out);

/* Static names for logs and tests. */
const char *hd_can_result_str(int result);
const char *hd_can_param_str(int param);

#ifdef __cplusplus
}
#endif

#endif /* HD_CAN_PROTO_H */
