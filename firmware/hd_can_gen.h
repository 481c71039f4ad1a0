/* hd_can_gen.h: the frames and commands of the CAN protocol as C types.
 * Generated from firmware/hd_protocol.def by `cd tools && ../.venv/bin/python -m hdtools.protocol --write`: do not edit. */
#ifndef HD_CAN_GEN_H
#define HD_CAN_GEN_H

/* Included by hd_can_proto.h (hal.h, the enums and the helpers first). */

/* FILTER_ENABLE (0x01): the filter on or off */
typedef struct {
    uint8_t enable; /* FilterEnable: 1 on, 0 off (SET_PARAM filter) */
} hd_can_cmd_filter_enable_t;

#define HD_CAN_ADD_MOTOR_ORDER_DIV 100.0f
/* ADD_MOTOR (0x10): add a motor-locked block */
typedef struct {
    float order; /* MotorOrder [1/rev]: lines per motor revolution */
    float q_nm2; /* MotorQ [Nm^2]: the block's process noise q */
} hd_can_cmd_add_motor_t;

#define HD_CAN_ADD_OUTPUT_ORDER_DIV 100.0f
/* ADD_OUTPUT (0x11): add an output-locked block */
typedef struct {
    float order; /* OutputOrder [1/rev]: lines per output revolution */
    float q_nm2; /* OutputQ [Nm^2]: the block's process noise q */
} hd_can_cmd_add_output_t;

#define HD_CAN_ADD_FIXED_FREQUENCY_HZ_DIV 100.0f
/* ADD_FIXED (0x12): add a block at a fixed frequency */
typedef struct {
    float frequency_hz; /* FixedFrequency [Hz]: the line's frequency, below Nyquist */
    float q_nm2; /* FixedQ [Nm^2]: the block's process noise q */
} hd_can_cmd_add_fixed_t;

/* BLOCK_ENABLE (0x13): one block on or off */
typedef struct {
    uint8_t index; /* BlockIndex: a configured block */
    uint8_t enable; /* BlockEnable: 1 on, 0 off; the other blocks keep their estimates */
} hd_can_cmd_block_enable_t;

/* BLOCK_GET (0x15): one field of a configured block, so a host can read a model back */
typedef struct {
    uint8_t index; /* BlockGetIndex: a configured block */
    uint8_t field; /* BlockGetField: HD_BLOCK_FIELD_* */
} hd_can_cmd_block_get_t;

/* SET_PARAM (0x20): set a parameter */
typedef struct {
    uint8_t id; /* SetParamId: parameter id (hd_params.def) */
    float value; /* SetParamValue: the new value, checked against the parameter's range */
} hd_can_cmd_set_param_t;

/* GET_PARAM (0x21): read a parameter */
typedef struct {
    uint8_t id; /* GetParamId: parameter id (hd_params.def) */
} hd_can_cmd_get_param_t;

/* CALIB_SAVE (0x31): the calibration to NVM */
typedef struct {
    uint32_t calibrated_unix_s; /* CalibUnixTime [s]: when the calibration was made, kept in the record */
} hd_can_cmd_calib_save_t;

/* VERSION (0x60): one version item */
typedef struct {
    uint8_t item; /* VersionItem: HD_INFO_* below 16 */
} hd_can_cmd_version_t;

/* INFO (0x61): one boot-record or counter item */
typedef struct {
    uint8_t item; /* InfoItem: HD_INFO_* 16 and above */
} hd_can_cmd_info_t;

/* PROFILE_SAVE (0x70): save a profile */
typedef struct {
    uint8_t source; /* ProfileSaveSource: 0 the running filter (snapshot at the next tick), 1 the uploaded lines */
} hd_can_cmd_profile_save_t;

/* PROFILE_LOAD (0x71): load a profile into the filter */
typedef struct {
    uint8_t source; /* ProfileLoadSource: 0 the stored record, 1 the uploaded lines; the filter takes it at the next tick */
} hd_can_cmd_profile_load_t;

/* PROFILE_PUT (0x73): upload one profile value; lines arrive in order, a before b */
typedef struct {
    uint8_t line; /* ProfilePutLine: line index 0..7, + 16 for b, + 32 for output-locked */
    uint8_t order; /* ProfilePutOrder: the line's order */
    float value_nm; /* ProfilePutValue [Nm]: a or b; line 0's a starts a new upload */
} hd_can_cmd_profile_put_t;

/* IDENT_START (0x74): an identification run: a multisine current added to the torque loop's command (TORQUE or ZERO_TORQUE), IDENT frames every tick */
typedef struct {
    uint8_t periods; /* IdentPeriods: periods of 2 s measured, after one to settle */
    float rms_a; /* IdentRms [A]: the excitation's rms; its peak must stay within half ctrl_current_limit_a */
} hd_can_cmd_ident_start_t;

/* Is opcode one a host may send (an HD_OPCODE row below 0x80)? */
bool hd_can_is_command(uint8_t opcode);
/* Opcodes whose ACK carries a u32 (value_u32) instead of a float. */
bool hd_can_ack_is_u32(uint8_t opcode);

#define HD_CAN_SETPOINT_TORQUE_NM_LSB 0.002f /* Nm */
#define HD_CAN_SETPOINT_POSITION_RAD_LSB 0.001f /* rad */
#define HD_CAN_SETPOINT_VELOCITY_RAD_S_LSB 0.001f /* rad/s */
#define HD_CAN_NA_SETPOINT_TORQUE_NM (1u << 2u)
#define HD_CAN_NA_SETPOINT_POSITION_RAD (1u << 3u)
#define HD_CAN_NA_SETPOINT_VELOCITY_RAD_S (1u << 4u)
/* SETPOINT (type 0x00, host -> joint): control setpoint: mode, sequence, torque, position, velocity; feeds the watchdog */
typedef struct {
    uint8_t mode; /* SpMode: hd_ctrl_mode_t: 0 STOP, 1 DAMP, 2 TORQUE, 3 IMPEDANCE, 4 ZERO_TORQUE; others refused */
    uint8_t seq; /* SpSeq: free-running; a repeated value is stale: it does not feed the watchdog */
    float torque_nm; /* SpTorque [Nm]: TORQUE setpoint, IMPEDANCE feed-forward */
    float position_rad; /* SpPosition [rad]: IMPEDANCE position */
    float velocity_rad_s; /* SpVelocity [rad/s]: IMPEDANCE velocity */
} hd_can_setpoint_t;

void hd_can_pack_setpoint(const hd_can_setpoint_t *v, uint8_t data[HD_CAN_DLC]);
/* Returns the HD_CAN_NA_* bits of values not available (an int at its
 * minimum, a checked float not finite); 0 if all are. */
uint32_t hd_can_unpack_setpoint(const uint8_t data[HD_CAN_DLC], hd_can_setpoint_t *v);
void hd_can_encode_setpoint(uint8_t node_id, const hd_can_setpoint_t *v, hal_can_frame_t *f);
/* HD_CAN_RES_OK, BAD_FRAME / BAD_LENGTH, or NOT_FINITE (a value not
 * available); the ranges are the firmware's to check. */
int hd_can_decode_setpoint(const hal_can_frame_t *f, hd_can_setpoint_t *v);

#define HD_CAN_NA_FEEDFORWARD_TORQUE_NM (1u << 0u)
/* FEEDFORWARD (type 0x01, host -> joint): expected torque from the robot controller */
typedef struct {
    float torque_nm; /* FfTorque [Nm]: the controller's expected torque */
    uint8_t seq; /* FfSeq: free-running; repeated values are not new data */
} hd_can_feedforward_t;

void hd_can_pack_feedforward(const hd_can_feedforward_t *v, uint8_t data[HD_CAN_DLC]);
/* Returns the HD_CAN_NA_* bits of values not available (an int at its
 * minimum, a checked float not finite); 0 if all are. */
uint32_t hd_can_unpack_feedforward(const uint8_t data[HD_CAN_DLC], hd_can_feedforward_t *v);
void hd_can_encode_feedforward(uint8_t node_id, const hd_can_feedforward_t *v, hal_can_frame_t *f);
/* HD_CAN_RES_OK, BAD_FRAME / BAD_LENGTH, or NOT_FINITE (a value not
 * available); the ranges are the firmware's to check. */
int hd_can_decode_feedforward(const hal_can_frame_t *f, hd_can_feedforward_t *v);

#define HD_CAN_TELEM_A_TORQUE_FILTERED_NM_LSB 0.01f /* Nm */
#define HD_CAN_TELEM_A_TORQUE_RAW_NM_LSB 0.01f /* Nm */
#define HD_CAN_TELEM_A_RIPPLE_NM_LSB 0.001f /* Nm */
#define HD_CAN_NA_TELEM_A_TORQUE_FILTERED_NM (1u << 0u)
#define HD_CAN_NA_TELEM_A_TORQUE_RAW_NM (1u << 1u)
#define HD_CAN_NA_TELEM_A_RIPPLE_NM (1u << 2u)
/* TELEM_A (type 0x02, joint -> host): filtered and raw torque, ripple, sequence */
typedef struct {
    float torque_filtered_nm; /* TorqueFiltered [Nm]: filtered torque; -327.68 = not available (invalid sample) */
    float torque_raw_nm; /* TorqueRaw [Nm]: raw torque; -327.68 = not available (invalid sample) */
    float ripple_nm; /* Ripple [Nm]: ripple: raw minus filtered, the oscillator blocks' sum */
    uint8_t seq; /* SeqA: sample sequence, equal in TELEM_A, TELEM_B and TELEM_C of one sample */
} hd_can_telem_a_t;

void hd_can_pack_telem_a(const hd_can_telem_a_t *v, uint8_t data[HD_CAN_DLC]);
/* Returns the HD_CAN_NA_* bits of values not available (an int at its
 * minimum, a checked float not finite); 0 if all are. */
uint32_t hd_can_unpack_telem_a(const uint8_t data[HD_CAN_DLC], hd_can_telem_a_t *v);
void hd_can_encode_telem_a(uint8_t node_id, const hd_can_telem_a_t *v, hal_can_frame_t *f);
/* 0, or -1 if f is not this frame type of a node of ours (8 bytes, classic). */
int hd_can_decode_telem_a(const hal_can_frame_t *f, hd_can_telem_a_t *v);

#define HD_CAN_TELEM_B_MOTOR_VELOCITY_RAD_S_LSB 0.001f /* rad/s */
#define HD_CAN_NA_TELEM_B_MOTOR_VELOCITY_RAD_S (1u << 0u)
/* TELEM_B (type 0x03, joint -> host): motor velocity, faults, filter status, sequence */
typedef struct {
    float motor_velocity_rad_s; /* MotorVelocity [rad/s]: motor velocity */
    uint32_t faults; /* Faults: HD_FAULT_* bits raised since the previous telemetry frame */
    uint8_t kf_status; /* KfStatus: HD_KF_STATUS_* bits since the previous telemetry frame */
    uint8_t seq; /* SeqB: sample sequence */
} hd_can_telem_b_t;

void hd_can_pack_telem_b(const hd_can_telem_b_t *v, uint8_t data[HD_CAN_DLC]);
/* Returns the HD_CAN_NA_* bits of values not available (an int at its
 * minimum, a checked float not finite); 0 if all are. */
uint32_t hd_can_unpack_telem_b(const uint8_t data[HD_CAN_DLC], hd_can_telem_b_t *v);
void hd_can_encode_telem_b(uint8_t node_id, const hd_can_telem_b_t *v, hal_can_frame_t *f);
/* 0, or -1 if f is not this frame type of a node of ours (8 bytes, classic). */
int hd_can_decode_telem_b(const hal_can_frame_t *f, hd_can_telem_b_t *v);

/* TELEM_C (type 0x04, joint -> host): motor and output angle, sequence */
typedef struct {
    uint32_t motor_counts; /* MotorCounts [counts]: the motor encoder's free-running count */
    uint32_t output_counts; /* OutputCounts [counts]: the output encoder's count, low 23 bits */
    bool has_output; /* OutputPresent: 1: the joint has an output encoder (else OutputCounts is 0) */
    uint8_t seq; /* SeqC: sample sequence */
} hd_can_telem_c_t;

void hd_can_pack_telem_c(const hd_can_telem_c_t *v, uint8_t data[HD_CAN_DLC]);
/* Returns the HD_CAN_NA_* bits of values not available (an int at its
 * minimum, a checked float not finite); 0 if all are. */
uint32_t hd_can_unpack_telem_c(const uint8_t data[HD_CAN_DLC], hd_can_telem_c_t *v);
void hd_can_encode_telem_c(uint8_t node_id, const hd_can_telem_c_t *v, hal_can_frame_t *f);
/* 0, or -1 if f is not this frame type of a node of ours (8 bytes, classic). */
int hd_can_decode_telem_c(const hal_can_frame_t *f, hd_can_telem_c_t *v);

#define HD_CAN_NA_GAINS_KP_NM_RAD (1u << 0u)
#define HD_CAN_NA_GAINS_KD_NM_S_RAD (1u << 1u)
/* GAINS (type 0x05, host -> joint): impedance gains kp and kd: latched, used by IMPEDANCE setpoints */
typedef struct {
    float kp_nm_rad; /* GainKp [Nm/rad]: impedance stiffness */
    float kd_nm_s_rad; /* GainKd [Nm s/rad]: impedance damping */
} hd_can_gains_t;

void hd_can_pack_gains(const hd_can_gains_t *v, uint8_t data[HD_CAN_DLC]);
/* Returns the HD_CAN_NA_* bits of values not available (an int at its
 * minimum, a checked float not finite); 0 if all are. */
uint32_t hd_can_unpack_gains(const uint8_t data[HD_CAN_DLC], hd_can_gains_t *v);
void hd_can_encode_gains(uint8_t node_id, const hd_can_gains_t *v, hal_can_frame_t *f);
/* HD_CAN_RES_OK, BAD_FRAME / BAD_LENGTH, or NOT_FINITE (a value not
 * available); the ranges are the firmware's to check. */
int hd_can_decode_gains(const hal_can_frame_t *f, hd_can_gains_t *v);

#define HD_CAN_CTRL_STATE_TORQUE_REF_NM_LSB 0.01f /* Nm */
#define HD_CAN_CTRL_STATE_CURRENT_A_LSB 0.001f /* A */
#define HD_CAN_NA_CTRL_STATE_TORQUE_REF_NM (1u << 3u)
#define HD_CAN_NA_CTRL_STATE_CURRENT_A (1u << 4u)
/* CTRL_STATE (type 0x06, joint -> host): control state with each telemetry pair when a drive is present: modes, limits, torque reference, current command */
typedef struct {
    uint8_t mode_asked; /* CtrlModeAsked: the mode the last setpoint asked for */
    uint8_t mode_run; /* CtrlModeRun: the mode that ran (safer than asked after a fault) */
    uint8_t limits; /* CtrlLimits: HD_CTRL_LIM_* that shaped the command: 1 torque, 2 velocity, 4 position, 8 current, 16 non-finite, 32 fallback */
    float torque_ref_nm; /* CtrlTorqueRef [Nm]: torque reference */
    float current_a; /* CtrlCurrent [A]: q-axis current command */
    uint8_t seq; /* CtrlSeq: the last setpoint's sequence */
    uint8_t flags; /* CtrlFlags: HD_CAN_CTRL_FLAG_*: 1 drive enabled, 2 watchdog, 4 STOP latched, 8 no drive */
} hd_can_ctrl_state_t;

void hd_can_pack_ctrl_state(const hd_can_ctrl_state_t *v, uint8_t data[HD_CAN_DLC]);
/* Returns the HD_CAN_NA_* bits of values not available (an int at its
 * minimum, a checked float not finite); 0 if all are. */
uint32_t hd_can_unpack_ctrl_state(const uint8_t data[HD_CAN_DLC], hd_can_ctrl_state_t *v);
void hd_can_encode_ctrl_state(uint8_t node_id, const hd_can_ctrl_state_t *v, hal_can_frame_t *f);
/* 0, or -1 if f is not this frame type of a node of ours (8 bytes, classic). */
int hd_can_decode_ctrl_state(const hal_can_frame_t *f, hd_can_ctrl_state_t *v);

#define HD_CAN_IDENT_CMD_A_LSB 0.001f /* A */
#define HD_CAN_IDENT_DRIVE_A_LSB 0.001f /* A */
#define HD_CAN_IDENT_FEEDBACK_NM_LSB 0.01f /* Nm */
#define HD_CAN_NA_IDENT_CMD_A (1u << 0u)
#define HD_CAN_NA_IDENT_DRIVE_A (1u << 1u)
#define HD_CAN_NA_IDENT_FEEDBACK_NM (1u << 2u)
/* IDENT (type 0x07, joint -> host): every tick of an identification run (IDENT_START): the law's current, the drive's, the feedback torque */
typedef struct {
    float cmd_a; /* IdentCmd [A]: the law's q-axis current command (before the excitation) */
    float drive_a; /* IdentDrive [A]: what the drive was told: the law's current plus the excitation, within ctrl_current_limit_a */
    float feedback_nm; /* IdentFeedback [Nm]: the torque the law fed back */
    uint8_t tick; /* IdentTick: the run's tick, low 8 bits (0 at the first) */
    uint8_t status; /* IdentStatus: 0 running, 1 done (the run's last tick), 2 stopped: the mode changed or a fallback ran, 3 stopped: the excitation would have crossed ctrl_current_limit_a */
} hd_can_ident_t;

void hd_can_pack_ident(const hd_can_ident_t *v, uint8_t data[HD_CAN_DLC]);
/* Returns the HD_CAN_NA_* bits of values not available (an int at its
 * minimum, a checked float not finite); 0 if all are. */
uint32_t hd_can_unpack_ident(const uint8_t data[HD_CAN_DLC], hd_can_ident_t *v);
void hd_can_encode_ident(uint8_t node_id, const hd_can_ident_t *v, hal_can_frame_t *f);
/* 0, or -1 if f is not this frame type of a node of ours (8 bytes, classic). */
int hd_can_decode_ident(const hal_can_frame_t *f, hd_can_ident_t *v);

/* CMD (type 0x10, host -> joint): command */
typedef struct {
    uint8_t opcode; /* Opcode: the command (its arguments: HD_ARG rows) */
    uint8_t token; /* Token: any value, echoed in the ACK so a host can match replies */
    union {
        hd_can_cmd_filter_enable_t filter_enable;
        hd_can_cmd_add_motor_t add_motor;
        hd_can_cmd_add_output_t add_output;
        hd_can_cmd_add_fixed_t add_fixed;
        hd_can_cmd_block_enable_t block_enable;
        hd_can_cmd_block_get_t block_get;
        hd_can_cmd_set_param_t set_param;
        hd_can_cmd_get_param_t get_param;
        hd_can_cmd_calib_save_t calib_save;
        hd_can_cmd_version_t version;
        hd_can_cmd_info_t info;
        hd_can_cmd_profile_save_t profile_save;
        hd_can_cmd_profile_load_t profile_load;
        hd_can_cmd_profile_put_t profile_put;
        hd_can_cmd_ident_start_t ident_start;
    } arg; /* by opcode; commands without arguments have no member */
} hd_can_cmd_t;

void hd_can_pack_cmd(const hd_can_cmd_t *v, uint8_t data[HD_CAN_DLC]);
/* Returns the HD_CAN_NA_* bits of values not available (an int at its
 * minimum, a checked float not finite); 0 if all are. */
uint32_t hd_can_unpack_cmd(const uint8_t data[HD_CAN_DLC], hd_can_cmd_t *v);
void hd_can_encode_cmd(uint8_t node_id, const hd_can_cmd_t *v, hal_can_frame_t *f);

/* ACK (type 0x11, joint -> host): one answer per command */
typedef struct {
    uint8_t opcode; /* AckOpcode: the command answered */
    uint8_t token; /* AckToken: the command's token */
    uint8_t result; /* AckResult: hd_can_result_t */
    uint8_t aux; /* AckAux: per command (HD_REPLY rows) */
    float value; /* AckValue: per command (HD_REPLY rows) */
    uint32_t value_u32; /* AckValueU32: per command (HD_REPLY rows) */
} hd_can_ack_t;

void hd_can_pack_ack(const hd_can_ack_t *v, uint8_t data[HD_CAN_DLC]);
/* Returns the HD_CAN_NA_* bits of values not available (an int at its
 * minimum, a checked float not finite); 0 if all are. */
uint32_t hd_can_unpack_ack(const uint8_t data[HD_CAN_DLC], hd_can_ack_t *v);
void hd_can_encode_ack(uint8_t node_id, const hd_can_ack_t *v, hal_can_frame_t *f);
/* 0, or -1 if f is not this frame type of a node of ours (8 bytes, classic). */
int hd_can_decode_ack(const hal_can_frame_t *f, hd_can_ack_t *v);

/* HEARTBEAT (type 0x20, joint -> host): state, faults, record status, 1 Hz */
typedef struct {
    uint8_t state; /* State: hd_fw_state_t */
    uint32_t faults; /* HbFaults: HD_FAULT_* bits raised since the previous heartbeat */
    uint16_t deadline_misses; /* DeadlineMisses: ticks not run on time, total, saturating */
    uint8_t calib_status; /* CalibStatus: calibration record status */
    uint8_t config_status; /* ConfigStatus: configuration record status */
    uint8_t profile_status; /* ProfileStatus: profile record status */
} hd_can_heartbeat_t;

void hd_can_pack_heartbeat(const hd_can_heartbeat_t *v, uint8_t data[HD_CAN_DLC]);
/* Returns the HD_CAN_NA_* bits of values not available (an int at its
 * minimum, a checked float not finite); 0 if all are. */
uint32_t hd_can_unpack_heartbeat(const uint8_t data[HD_CAN_DLC], hd_can_heartbeat_t *v);
void hd_can_encode_heartbeat(uint8_t node_id, const hd_can_heartbeat_t *v, hal_can_frame_t *f);
/* 0, or -1 if f is not this frame type of a node of ours (8 bytes, classic). */
int hd_can_decode_heartbeat(const hal_can_frame_t *f, hd_can_heartbeat_t *v);

/* BOOT (type 0x21, joint -> host): once after boot: reset cause, fault record, versions */
typedef struct {
    uint8_t reset_cause; /* ResetCause: HAL_RESET_* bits */
    bool fault_valid; /* FaultRecord: a HardFault record survived (INFO FAULT_*) */
    bool config_from_record; /* ConfigFromRecord: booted from the saved configuration */
    uint32_t fault_pc; /* FaultPc: PC of that HardFault, 0 if none */
    uint8_t protocol_version; /* ProtocolVersion: HD_CAN_PROTOCOL_VERSION */
    uint8_t config_status; /* BootConfigStatus: configuration record status */
} hd_can_boot_t;

void hd_can_pack_boot(const hd_can_boot_t *v, uint8_t data[HD_CAN_DLC]);
/* Returns the HD_CAN_NA_* bits of values not available (an int at its
 * minimum, a checked float not finite); 0 if all are. */
uint32_t hd_can_unpack_boot(const uint8_t data[HD_CAN_DLC], hd_can_boot_t *v);
void hd_can_encode_boot(uint8_t node_id, const hd_can_boot_t *v, hal_can_frame_t *f);
/* 0, or -1 if f is not this frame type of a node of ours (8 bytes, classic). */
int hd_can_decode_boot(const hal_can_frame_t *f, hd_can_boot_t *v);

#endif /* HD_CAN_GEN_H */
