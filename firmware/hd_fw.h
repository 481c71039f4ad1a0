/*
 * hd_fw: the joint firmware core, in two contexts.
 *
 *   hd_fw_isr         the 1 kHz tick (hd_fw_tick.c), a list of stage calls
 *                     (hd_fw_stages.h): deadline -> requests -> receive ->
 *                     gauge -> encoders -> current -> feed-forward ->
 *                     filter (expected torque inside) -> control -> faults
 *                     -> telemetry
 *                     Bounded time: it never parses a command, builds a
 *                     model or touches NVM.  It takes the frames the HAL
 *                     received (feed-forward applied at once, commands queued
 *                     for the background), applies the model or settings the
 *                     background prepared (a swap of two indices), runs the
 *                     torque path and sends telemetry, heartbeat and ACKs.
 *   hd_fw_background  the main loop (hd_fw_cmd.c, hd_fw_records.c): decodes
 *                     and executes queued commands, builds new models in the
 *                     spare slot, reads and writes the NVM records, queues
 *                     ACKs.  It may be interrupted by the tick at any point.
 *
 * The two talk through single-producer single-consumer queues and one
 * request mailbox (hd_fw_request_t); every shared field has exactly one
 * writer (docs/design/firmware.md, "Two contexts").  On the host both are called
 * from one thread, tick then background.
 *
 * All state lives in hd_fw_t, which the caller allocates (statically on the
 * MCU).  No stdio, heap or OS calls: this builds with arm-none-eabi.
 */
#ifndef HD_FW_H
#define HD_FW_H

#include <stdbool.h>
#include <stdint.h>

#include "hal.h"
#include "hd_calib_record.h"
#include "hd_ctrl.h"
#include "hd_excite.h"
#include "hd_can_proto.h"
#include "hd_fw_config.h"
#include "hd_fw_stages.h"
#include "hd_params.h"
#include "hd_pipeline.h"
#include "hd_record_store.h"

#ifdef __cplusplus
extern "C" {
#endif

/* Plausibility bounds of a calibration record (outside them it counts as
 * corrupt); the same bounds as the table's calib_gain / calib_offset rows. */
#define HD_FW_CALIB_GAIN_MAX_NM_PER_V 1.0e4f
#define HD_FW_CALIB_OFFSET_MAX_V 100.0f

#define HD_FW_RX_PER_TICK 2u      /* frames the tick takes from the HAL, at most */
#define HD_FW_QUEUE_LEN 16u       /* command and ACK queues (a power of two) */
#define HD_FW_ACKS_PER_TICK 1u    /* ACKs the tick sends, at most */
#define HD_FW_CMDS_PER_CALL 2u    /* commands one background call handles, at most */
#define HD_FW_HEARTBEAT_TICKS 1000u

/* Per-fault and per-event counters.  Each field has one writer: the tick,
 * except commands, command_errors (background). */
typedef struct {
    uint32_t ticks;
    uint32_t valid_samples;
    uint32_t fault_ticks;              /* ticks with any fault bit */
    uint32_t by_fault[HD_FAULT_COUNT]; /* ticks (or events) per HD_FAULT_* bit */
    uint32_t deadline_misses;
    uint32_t telemetry_frames;
    uint32_t frames_dropped;           /* transmit queue full or bus off */
    uint32_t foreign_frames;           /* received, not addressed to this node */
    uint32_t command_queue_full;       /* ticks that left frames with the driver: queue full */
    uint32_t commands;                 /* background */
    uint32_t command_errors;           /* background */
    uint32_t feedforward_frames;       /* accepted feed-forward frames */
    uint32_t profile_imports;          /* profiles the filter took (boot, load, restarts) */
    uint32_t unmodelled_steps;         /* ticks beyond the held offset-jump gate */
    uint32_t correction_limited;       /* ticks with the correction at correction_max_nm */
} hd_fw_counters_t;

/* What the last tick produced (for the host runner and tests).  The tick
 * fills it in place (fw->last): read it between ticks, not during one.
 * Nothing clears it first: each field's stage writes it on every tick. */
typedef struct {
    uint64_t t_us;                 /* clock at the start of the tick (0 without a clock) */
    int32_t bridge_counts;
    float bridge_v;
    float torque_raw_nm;           /* NaN if the sample was invalid */
    float torque_filtered_nm;      /* NaN if the sample was invalid */
    float ripple_nm;
    float torque_expected_nm;
    float torque_expected_var_nm2; /* the variance of T_exp's error the filter was given */
    float feedforward_nm;          /* feed-forward in T_exp this tick (after the stale fallback) */
    float motor_current_a;         /* NaN without a current channel */
    float motor_velocity_rad_s;    /* the motor increment over the tick (the current term uses it / N) */
    float d_motor_angle_rad;       /* increment used (after glitch rejection) */
    float d_output_angle_rad;
    uint32_t motor_counts;         /* as read (TELEM_C) */
    uint32_t output_counts;
    bool has_output;
    bool valid;
    uint32_t faults;               /* HD_FAULT_* raised this tick */
    uint32_t kf_status;
} hd_fw_sample_t;

/* Everything the tick reads from the configuration, swapped as a whole. */
typedef struct {
    hd_fw_config_t cfg;
    hd_ctrl_plan_t ctrl;            /* hd_ctrl_plan of hd_fw_ctrl_config(cfg) */
    uint32_t ctrl_gen;              /* changes when ctrl does, but for its motor orders
                                       (hd_fw_derive_next) */
    float motor_rad_per_count;
    float output_rad_per_count;
    int32_t max_motor_delta_counts;
    int32_t max_output_delta_counts;
    uint32_t telem_divider;         /* ticks per telemetry frame, 0 = off */
    hd_slow_current_config_t current; /* the current term (cfg.current, current_filter_hz) */
    uint32_t record_faults;         /* sticky HD_FAULT_CALIB_* / CONFIG_DEFAULTS */
    uint8_t calib_status;           /* hd_record_status_t */
    uint8_t config_status;
    uint8_t profile_status;
} hd_fw_settings_t;

/* One CAN frame of at most 8 data bytes, as queued between the contexts. */
typedef struct {
    uint32_t id;
    uint8_t len;
    uint8_t flags;
    uint8_t data[8];
} hd_fw_frame8_t;

/* Single producer, single consumer: the producer writes slot[head] then
 * head; the consumer reads slot[tail] then tail. */
typedef struct {
    hd_fw_frame8_t slot[HD_FW_QUEUE_LEN];
    volatile uint32_t head;
    volatile uint32_t tail;
} hd_fw_queue_t;

#define HD_FW_REQ_SETTINGS 0x01u /* make settings[!live] live */
#define HD_FW_REQ_PIPE     0x02u /* make pipe[!live] live */
#define HD_FW_REQ_KF_RESET 0x04u /* reset the live filter */
#define HD_FW_REQ_BLOCK    0x08u /* enable/disable one block of the live filter */
#define HD_FW_REQ_PROFILE  0x10u /* the live filter takes hd_fw_bg_state_t.profile */
#define HD_FW_REQ_SNAPSHOT 0x20u /* export the live filter into hd_fw_filter_t.snapshot */
#define HD_FW_REQ_IDENT    0x40u /* start the identification run hd_fw_ident_t holds */

/* The background fills it and sets pending; the tick applies it at the
 * start of the next tick and clears pending. */
typedef struct {
    volatile uint8_t pending;
    uint8_t flags;                 /* HD_FW_REQ_* */
    uint8_t block;
    uint8_t enable;
} hd_fw_request_t;

/* The tick's own state (the stages' are in hd_fw_stages.h): only the tick
 * writes it. */
typedef struct {
    bool have_prev_time;
    uint64_t prev_t_us;
    uint32_t pending_faults;        /* raised between samples (transmit drops) */
    uint32_t command_errors_seen;   /* CMD_ERROR raised when the background's count moves */
    volatile uint8_t state;         /* hd_fw_state_t */
    volatile bool ended;            /* the sensors reported HAL_ERR_END */
} hd_fw_tick_state_t;

/* The control stage's state (hd_fw_control.c): only the tick writes it. */
typedef struct {
    hd_ctrl_t ctrl;                 /* the law's state, on the live settings' plan */
    const hd_fw_settings_t *built_from; /* the settings whose plan ctrl uses */
    uint32_t built_gen;             /* their ctrl_gen: the law restarts only when it moves */
    hd_ctrl_setpoint_t sp;          /* the last accepted setpoint (STOP at boot) */
    float kp_nm_rad;                /* the last accepted GAINS */
    float kd_nm_s_rad;
    bool sp_have;
    uint8_t sp_seq;
    uint32_t sp_age_ticks;          /* ticks since the last new setpoint (saturating) */
    bool stop_latched;              /* encoder lost or drive fault: STOP until a STOP setpoint */
    bool watchdog;                  /* the stream timed out (until a new setpoint) */
    bool drive_on;                  /* what the drive was last told */
    uint32_t misses_seen;           /* counters.deadline_misses at the last tick */
    uint32_t miss_score;            /* +HD_FW_MISS_WEIGHT per missed tick, -1 per tick */
    uint32_t bus_off_hold_ticks;    /* DAMP for this many more ticks (the last bus-off) */
    float angle_rad;                /* output angle since boot (compensated sum) */
    float angle_comp_rad;
    float angle_fine_rad;           /* where in the output encoder's count: 0..one count */
    /* a refused SETPOINT / GAINS frame's ACK, sent by publish */
    bool refuse_pending;
    uint8_t refuse_node;
    uint8_t refuse_token;
    uint8_t refuse_aux;
    uint8_t refuse_result;
    hd_ctrl_input_t in;             /* the last step's inputs */
    hd_ctrl_output_t out;           /* the last step's */
} hd_fw_ctrl_state_t;

/* The IDENT frame's status (hd_protocol.def, IdentStatus). */
#define HD_FW_IDENT_PERIODS_MAX 60u /* IdentPeriods' range (hd_protocol.def) */
#define HD_FW_IDENT_RUNNING 0u
#define HD_FW_IDENT_DONE    1u
#define HD_FW_IDENT_MODE    2u /* stopped: the mode changed, a fallback ran, the drive is off */
#define HD_FW_IDENT_LIMIT   3u /* stopped: the excitation would have crossed the current limit */

/* An identification run (hd_fw_ident.c): the background builds the
 * waveform and the length while no run is on, then posts HD_FW_REQ_IDENT;
 * the tick runs it and writes the rest. */
typedef struct {
    hd_excite_t excite;             /* background, only while !running */
    uint32_t ticks_total;           /* background: (periods + 1) x HD_EXCITE_PERIOD_TICKS */
    volatile bool running;          /* tick */
    uint32_t tick;                  /* ticks run */
    bool frame_pending;             /* an IDENT frame for publish */
    hd_can_ident_t frame;
} hd_fw_ident_t;

/* Repeated deadline misses (the DAMP reaction): each missed tick adds this,
 * each tick takes 1 away; at HD_FW_MISS_DAMP_SCORE or more the controller
 * runs DAMP.  One late tick now and then never trips it; 3 within ~20 ticks do. */
#define HD_FW_MISS_WEIGHT 10u
#define HD_FW_MISS_DAMP_SCORE 21u

/* State only the background writes. */
typedef struct {
    hd_fw_config_t defaults;        /* hd_fw_init's: CONFIG_DEFAULTS returns to them */
    hd_calib_record_t calib;        /* the stored record's metadata (date, serial, ...) */
    bool config_from_record;
    hal_boot_info_t boot;
    uint8_t reboot_pending;         /* REBOOT acknowledged: restart once the ACK is out */
    uint8_t work[HD_STORE_IMAGE_MAX]; /* record store saves */
    /* The profile a restarting filter starts from (boot, rebuild, reset,
     * PROFILE_LOAD): read by the tick only while applying a request. */
    hd_kf_profile_t profile;
    hd_kf_profile_t upload;         /* PROFILE_PUT lines */
    uint16_t upload_mask;           /* bit 2i: line i's a, 2i + 1: its b */
    /* A PROFILE_SAVE waiting for the tick's snapshot (ACK sent when saved). */
    bool save_pending;
    uint8_t save_node;
    uint32_t save_snapshot_seq;
    hd_can_cmd_t save_cmd;
} hd_fw_bg_state_t;

typedef struct {
    const hal_t *hal;
    hd_fw_settings_t settings[2];
    hd_pipeline_t pipe[2];
    volatile uint8_t live_settings; /* written by the tick only */
    volatile uint8_t live_pipe;     /* written by the tick only */
    hd_fw_request_t request;
    hd_fw_queue_t cmd_queue;        /* tick -> background */
    hd_fw_queue_t ack_queue;        /* background -> tick */
    /* the tick's stages (hd_fw_stages.h), in the order it runs them */
    hd_fw_tick_state_t tick;
    hd_fw_gauge_t gauge;
    hd_fw_encoder_t encoder;
    hd_fw_current_t current;
    hd_fw_ff_t ff;
    hd_fw_filter_t filter;
    hd_fw_ctrl_state_t control;     /* written by the tick only */
    hd_fw_ident_t ident;
    hd_fw_telem_t telem;
    hd_fw_bg_state_t bg;
    hd_fw_sample_t last;
    hd_fw_counters_t counters;
} hd_fw_t;

/* Boots the firmware: loads the records from hal->nvm (calibration,
 * configuration; a missing or unusable one leaves defaults and a sticky
 * fault flag), falls back to *defaults for the configuration when there is
 * no usable saved one, and builds the pipeline.  *defaults must pass
 * hd_fw_config_check.  On error fw is unusable and nothing was sent. */
int hd_fw_init(hd_fw_t *fw, const hal_t *hal, const hd_fw_config_t *defaults);

/* The 1 ms tick body. */
void hd_fw_isr(hd_fw_t *fw);

/* Commands, model builds and NVM work.  Call from the main loop; returns
 * true if it did something. */
bool hd_fw_background(hd_fw_t *fw);

/* The runner reports ticks it could not run on time (real-time mode). */
void hd_fw_note_deadline_miss(hd_fw_t *fw, uint32_t missed_ticks);

/* Handles one command frame as the background would (exposed for tests and
 * fuzzing): frames for other ids are ignored.  The ACK is queued. */
void hd_fw_handle_frame(hd_fw_t *fw, const hal_can_frame_t *frame);

/* The HAL's NVM part as the record store's I/O (work may be NULL for
 * loads only). */
hd_store_io_t hd_fw_store_io(const hal_t *hal, uint8_t *work, size_t work_size);

const hd_fw_sample_t *hd_fw_last_sample(const hd_fw_t *fw);
const hd_fw_counters_t *hd_fw_counters(const hd_fw_t *fw);
/* The running configuration (the live settings). */
const hd_fw_config_t *hd_fw_config(const hd_fw_t *fw);
/* Load status of a record kind (hd_record_status_t). */
int hd_fw_record_status(const hd_fw_t *fw, hd_record_kind_t kind);

#ifdef __cplusplus
}
#endif

#endif /* HD_FW_H */
