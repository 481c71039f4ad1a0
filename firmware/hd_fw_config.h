/*
 * hd_fw_config: the firmware's running configuration, its defaults and its
 * checks.  Every field a user can set is a row of hd_params.def (key, CAN
 * id, range, how it takes effect, which record keeps it).
 *
 * Pure: no I/O, no heap, no globals.
 */
#ifndef HD_FW_CONFIG_H
#define HD_FW_CONFIG_H

#include <stdint.h>

#include "hd_ctrl.h"
#include "hd_expected.h"
#include "hd_kf.h"

#ifdef __cplusplus
extern "C" {
#endif

#define HD_FW_TICK_HZ 1000u
#define HD_FW_TS_S 0.001f
#define HD_FW_TS_US 1000u

/* The firmware default tuning (hd_kf_config_recommended's arguments). */
#define HD_FW_DEFAULT_NOISE_NM 0.02f
#define HD_FW_DEFAULT_RIPPLE_SETTLE_S 0.05f
#define HD_FW_DEFAULT_OFFSET_SETTLE_S 0.02f
/* The other defaults are the default column of hd_params.def. */
/* ripple_load_coeff_per_nm x torque_limit_nm at most this (a line 101x its
 * zero-load amplitude at the limit). */
#define HD_FW_MAX_LOAD_GROWTH 100.0f

typedef struct {
    hd_kf_config_t kf;              /* ts_s must be HD_FW_TS_S */
    hd_expected_config_t expected;
    hd_expected_current_config_t current; /* motor-current term of T_exp (all 0 = unused) */
    float current_filter_hz;        /* low-pass of the current before T_exp, 0 = none */
    float track_bandwidth_hz;       /* output-angle tracking loop */
    float gear_ratio;               /* motor revs per output rev, >= 1 */
    uint32_t motor_cpr;             /* motor encoder counts per rev */
    uint32_t output_cpr;            /* output encoder counts per rev (if present) */
    float adc_volts_per_count;      /* bridge amplifier volts per ADC count */
    float torque_limit_nm;          /* |torque| above this is out of range */
    float max_motor_speed_rad_s;    /* faster count changes are glitches */
    float calib_gain_nm_per_v;      /* live calibration (the calibration record keeps it) */
    float calib_offset_v;
    uint16_t telemetry_rate_hz;     /* 0 = off, else 1..1000 (period rounded to whole ticks) */
    uint16_t angle_telemetry_every; /* TELEM_C with every Nth TELEM_A/B pair, 0 = off */
    uint16_t feedforward_timeout_ms; /* 0: no feed-forward expected (frames ignored) */
    uint16_t feedforward_ramp_ms;   /* stale: the last value ramps to 0 over this */
    float operating_output_learn_scale; /* kf.output_learn_scale in operating mode */
    uint8_t learning_mode;          /* HD_FW_LEARN_* */
    uint8_t node_id;                /* 1..127 */
    uint8_t filter_enabled;         /* 0: filtered torque = raw torque */
    hd_ctrl_config_t ctrl;          /* the joint controller (issue 23; its ts_s and
                                       gear_ratio are the firmware's: hd_fw_ctrl_config) */
    uint16_t ctrl_watchdog_ms;      /* no new setpoint for this long: DAMP */
    uint16_t ctrl_damp_ms;          /* then DAMP this long, then STOP */
} hd_fw_config_t;

/* learning_mode: how fast output-locked (geometric) blocks learn
 * (docs/design/slow-torque.md, "Learning schedule"). */
#define HD_FW_LEARN_ADAPTIVE 0u      /* every block at its full rate (before issue 12) */
#define HD_FW_LEARN_OPERATING 1u     /* output-locked at operating_output_learn_scale */
#define HD_FW_LEARN_COMMISSIONING 2u /* no or a known load: output-locked at full rate,
                                        the offset HD_FW_COMMISSIONING_OFFSET_Q_SCALE slower */
/* Commissioning: the offset's random walk times this (settles 10x slower),
 * so that it does not take a share of the slow output-locked lines. */
#define HD_FW_COMMISSIONING_OFFSET_Q_SCALE 0.01f

/* The firmware library's errors (configuration, parameters, configuration
 * text).  hd_fw_err_str names each. */
typedef enum {
    HD_FW_OK = 0,
    HD_FW_ERR_NULL = -1,
    HD_FW_ERR_KF = -2,            /* hd_kf_config_check refused the model */
    HD_FW_ERR_EXPECTED = -3,      /* hd_expected_config_check refused it */
    HD_FW_ERR_RANGE = -4,         /* a value outside its hd_params.def range */
    HD_FW_ERR_TS = -5,            /* kf.ts_s != 1 ms */
    HD_FW_ERR_HAL = -6,           /* the HAL has no sensors part */
    HD_FW_ERR_UNKNOWN_PARAM = -7, /* no such parameter id or key */
    HD_FW_ERR_READ_ONLY = -8,     /* a read-only parameter */
    HD_FW_ERR_NOT_FINITE = -9,    /* NaN or infinity */
    HD_FW_ERR_NOT_WHOLE = -10,    /* an integer or flag parameter given a fraction */
    HD_FW_ERR_SYNTAX = -11,       /* a line that cannot be read (missing value, bad number) */
    HD_FW_ERR_TOO_MANY_BLOCKS = -12,
    HD_FW_ERR_DUPLICATE = -13,    /* a key given twice */
    HD_FW_ERR_BYTES = -14,        /* NUL, control or non-ASCII byte outside a comment */
    HD_FW_ERR_TOO_LONG = -15,     /* configuration text above HD_CFGTXT_MAX_BYTES */
    HD_FW_ERR_CONTROL = -16,      /* hd_ctrl_config_check refused the controller's settings */
} hd_fw_err_t;

/* The defaults: hd_kf_config_recommended (motor orders 2 and 4, output
 * order 1, offset state; noise and settle times above), gear ratio 100,
 * 4096-count encoders, 10 V / 2^15 counts, torque limit 200 Nm, glitch limit
 * 1000 rad/s, calibration 6.60 Nm/V and 0 V (Taghirad 1997, Table I),
 * telemetry at 1 kHz with TELEM_C every 10th frame, node 1, filter on. */
void hd_fw_config_default(hd_fw_config_t *cfg);

/* Checks every field against its table range, then the parts as a whole
 * (hd_kf_config_check, hd_expected_config_check).  Returns HD_FW_OK or the
 * first error; *bad_param (may be NULL) names the parameter id of a range
 * error, else 0. */
hd_fw_err_t hd_fw_config_check(const hd_fw_config_t *cfg, unsigned *bad_param);

/* The filter configuration the firmware runs: cfg->kf with
 * output_learn_scale (and, commissioning, the offset's q) set by the
 * learning mode; q_motion_ref_profiled_rad only in operating mode (0, off,
 * in the learning modes). */
void hd_fw_kf_config(const hd_fw_config_t *cfg, hd_kf_config_t *out);

/* The controller configuration the firmware runs: cfg->ctrl with the tick
 * period and cfg->gear_ratio. */
void hd_fw_ctrl_config(const hd_fw_config_t *cfg, hd_ctrl_config_t *out);
const char *hd_fw_err_str(int err);

#ifdef __cplusplus
}
#endif

#endif /* HD_FW_CONFIG_H */
