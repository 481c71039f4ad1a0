/*
 * hd_fw: the joint firmware core.  One function, hd_fw_isr, is the body of
 * the 1 kHz tick:
 *
 *   CAN commands (at most HD_FW_RX_PER_TICK frames) -> read ADC and encoder
 *   -> calibration (gain, offset) -> encoder deltas with glitch rejection
 *   -> hd_pipeline_step (tracker, expected torque, Kalman filter)
 *   -> fault flags and counters -> telemetry and heartbeat frames.
 *
 * It never blocks, never allocates and has a bounded worst case.  Work that
 * may take long (writing the calibration record to flash) is only requested
 * by the ISR and done by hd_fw_background, called from the main loop.
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
#include "hd_can_proto.h"
#include "hd_pipeline.h"

#ifdef __cplusplus
extern "C" {
#endif

#define HD_FW_TICK_HZ 1000u
#define HD_FW_TS_S 0.001f
#define HD_FW_TS_US 1000u
/* Plausibility bounds for a calibration (record or CAN): outside them the
 * record counts as corrupt / the command is out of range. */
#define HD_FW_CALIB_GAIN_MAX_NM_PER_V 1.0e4f
#define HD_FW_CALIB_OFFSET_MAX_V 100.0f
#define HD_FW_RX_PER_TICK 4u       /* command frames handled per tick, at most */
#define HD_FW_HEARTBEAT_TICKS 1000u
#define HD_FW_TARE_TICKS 64u       /* tare averages the last this many valid samples */

typedef struct {
    hd_kf_config_t kf;              /* ts_s must be HD_FW_TS_S */
    hd_expected_config_t expected;
    float track_bandwidth_hz;       /* output-angle tracking loop */
    float gear_ratio;               /* motor revs per output rev, > 1 */
    uint32_t motor_cpr;             /* motor encoder counts per rev */
    uint32_t output_cpr;            /* output encoder counts per rev (if present) */
    float adc_volts_per_count;      /* bridge amplifier volts per ADC count */
    float torque_limit_nm;          /* |torque| above this is out of range */
    float max_motor_speed_rad_s;    /* faster count changes are glitches */
    uint16_t telemetry_rate_hz;     /* 0 = off, else 1..1000 (period rounded to whole ticks) */
    uint8_t node_id;                /* 1..127 */
    uint8_t filter_enabled;         /* 0: filtered torque = raw torque */
} hd_fw_config_t;

typedef enum {
    HD_FW_OK = 0,
    HD_FW_ERR_NULL = -1,
    HD_FW_ERR_KF = -2,          /* hd_kf_config_check failed */
    HD_FW_ERR_EXPECTED = -3,    /* hd_expected_config_check failed */
    HD_FW_ERR_BANDWIDTH = -4,   /* tracker bandwidth not usable at 1 kHz */
    HD_FW_ERR_GEAR = -5,        /* gear ratio not finite or < 1 */
    HD_FW_ERR_CPR = -6,         /* encoder counts per rev 0 */
    HD_FW_ERR_ADC = -7,         /* adc_volts_per_count not finite or <= 0 */
    HD_FW_ERR_LIMIT = -8,       /* torque limit or max speed not finite or <= 0 */
    HD_FW_ERR_RATE = -9,        /* telemetry rate > 1000 */
    HD_FW_ERR_NODE = -10,       /* node id outside 1..127 */
    HD_FW_ERR_TS = -11,         /* kf.ts_s != 1 ms */
    HD_FW_ERR_HAL = -12,        /* hal has no sensors part */
} hd_fw_err_t;

/* Per-fault counters (index = bit number of the HD_FAULT_* flag). */
typedef struct {
    uint32_t ticks;
    uint32_t valid_samples;
    uint32_t fault_ticks;              /* ticks with any fault bit */
    uint32_t by_fault[HD_FAULT_COUNT]; /* ticks (or events) per HD_FAULT_* bit */
    uint32_t deadline_misses;
    uint32_t telemetry_frames;
    uint32_t commands;
    uint32_t command_errors;
} hd_fw_counters_t;

/* What the last tick produced (for the host runner and tests). */
typedef struct {
    uint64_t t_us;                 /* clock at the start of the tick (0 without a clock) */
    int32_t bridge_counts;
    float bridge_v;
    float torque_raw_nm;           /* NaN if the sample was invalid */
    float torque_filtered_nm;      /* NaN if the sample was invalid */
    float ripple_nm;
    float torque_expected_nm;
    float motor_velocity_rad_s;
    float d_motor_angle_rad;       /* increment used (after glitch rejection) */
    float d_output_angle_rad;
    bool valid;
    uint16_t faults;               /* HD_FAULT_* raised this tick */
    uint32_t kf_status;
} hd_fw_sample_t;

typedef struct {
    hd_fw_config_t cfg;
    const hal_t *hal;
    hd_pipeline_t pipe;
    hd_pipeline_t scratch;          /* a new model is built here, then swapped in */
    hd_calib_record_t calib;
    int calib_load_result;          /* HD_CALIB_LOAD_* */
    uint32_t calib_seq;
    uint16_t calib_faults;          /* HD_FAULT_CALIB_* while defaults are in use */

    /* encoder state */
    bool have_prev;
    bool output_present;            /* the last good read had an output encoder */
    uint32_t prev_motor_counts;
    uint32_t prev_output_counts;
    int32_t last_good_motor_delta;
    int32_t last_good_output_delta;
    int32_t max_motor_delta_counts;
    int32_t max_output_delta_counts;
    float motor_rad_per_count;
    float output_rad_per_count;

    /* tare: running sum of the last HD_FW_TARE_TICKS valid bridge voltages */
    float tare_v[HD_FW_TARE_TICKS];
    float tare_sum_v;
    uint32_t tare_n;
    uint32_t tare_next;

    /* timing */
    bool have_prev_time;
    uint64_t prev_t_us;

    /* telemetry */
    uint32_t telem_divider;         /* 0: off */
    uint32_t telem_countdown;
    uint8_t telem_seq;
    uint16_t telem_faults;          /* faults since the last telemetry frame */
    uint8_t telem_kf_status;
    uint16_t hb_faults;             /* faults since the last heartbeat */
    uint32_t hb_countdown;
    uint8_t state;                  /* hd_fw_state_t */
    uint16_t pending_faults;        /* raised outside a tick (commands, runner) */

    /* work for hd_fw_background */
    uint8_t nvm_pending;            /* 0 none, 1 save, 2 load */
    uint8_t nvm_token;
    uint32_t nvm_unix_s;

    bool ended;                     /* the sensors reported HAL_ERR_END */
    hd_fw_sample_t last;
    hd_fw_counters_t counters;
} hd_fw_t;

#define HD_FW_DEFAULT_NOISE_NM 0.02f
#define HD_FW_DEFAULT_RIPPLE_SETTLE_S 0.05f
#define HD_FW_DEFAULT_OFFSET_SETTLE_S 0.02f

/* The defaults: hd_kf_config_recommended (motor orders 2 and 4, output
 * order 1, offset state; noise and settle times above), gear ratio 100,
 * 4096-count encoders, 10 V / 2^15 counts, torque limit 200 Nm, glitch limit
 * 1000 rad/s, telemetry at 1 kHz, node 1, filter enabled. */
void hd_fw_config_default(hd_fw_config_t *cfg);

/* Checks every field; returns HD_FW_OK or the first hd_fw_err_t found. */
int hd_fw_config_check(const hd_fw_config_t *cfg);
const char *hd_fw_err_str(int err);

/* Checks cfg, loads the calibration record from hal->nvm (missing or corrupt:
 * safe defaults and a sticky HD_FAULT_CALIB_* flag), initialises the
 * pipeline.  On error fw is unusable and nothing was sent. */
int hd_fw_init(hd_fw_t *fw, const hal_t *hal, const hd_fw_config_t *cfg);

/* The HAL's NVM part as the calibration library's storage callbacks. */
hd_calib_storage_t hd_fw_calib_storage(const hal_t *hal);

/* The 1 ms tick body. */
void hd_fw_isr(hd_fw_t *fw);

/* Slow work requested by commands (NVM save / load).  Call from the main
 * loop; returns true if it did something. */
bool hd_fw_background(hd_fw_t *fw);

/* The runner reports ticks it could not run on time (real-time mode). */
void hd_fw_note_deadline_miss(hd_fw_t *fw, uint32_t missed_ticks);

/* Handles one received frame as the ISR would (exposed for tests/fuzzing):
 * frames for other ids are ignored. */
void hd_fw_handle_frame(hd_fw_t *fw, const hal_can_frame_t *frame);

const hd_fw_sample_t *hd_fw_last_sample(const hd_fw_t *fw);
const hd_fw_counters_t *hd_fw_counters(const hd_fw_t *fw);

#ifdef __cplusplus
}
#endif

#endif /* HD_FW_H */
