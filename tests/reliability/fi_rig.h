/*
 * fi_rig: the fault-injection rig shared by the reliability tests.
 *
 * The firmware (hd_fw) runs on a composed HAL:
 *   sensors, clock  <- the simulated joint (hal/sim), wrapped by an injector
 *                      that corrupts what the firmware reads inside a window
 *                      of ticks (the truth is never touched);
 *   CAN, NVM        <- the in-memory mock (hal/mock), whose transmit hook
 *                      decodes every telemetry frame by the documented byte
 *                      layout (docs/design/firmware.md), independently of the
 *                      firmware's own decoder.
 *
 * Every tick the rig checks the invariants of the issue (the ISR takes one
 * step per call, no deadline miss, telemetry every tick, outputs finite and
 * bounded) and records the filtered-torque error against the simulation's
 * ground truth, so a test can measure the recovery time after a fault.
 *
 * Host-only test code: doubles and libm are fine here.
 */
#ifndef FI_RIG_H
#define FI_RIG_H

#include <stdbool.h>
#include <stdint.h>

#include "hal_mock.h"
#include "hal_sim.h"
#include "hd_fw.h"

/* What the injector does inside [start_tick, end_tick). */
typedef enum {
    FI_NONE = 0,
    FI_ADC_IO,        /* adc_read returns HAL_ERR_IO */
    FI_ADC_RAIL,      /* counts stuck at the positive rail, saturated flag set */
    FI_OPEN_BRIDGE,   /* adc_read returns HAL_ERR_FAULT (open bridge) */
    FI_ADC_COUNTS,    /* counts replaced by `counts` (an out-of-range torque) */
    FI_ENC_FAULT,     /* encoder reports a fault (counts unusable) */
    FI_ENC_SPIKE,     /* motor counts + `counts` on the window's ticks only */
    FI_ENC_JUMP,      /* from start_tick on, `counts` counts are lost for good */
    FI_EXTRA_RIPPLE,  /* from start_tick on, a motor order-2 line of `amp_nm`
                         appears in the sensor (a ripple amplitude change) */
} fi_kind_t;

typedef struct {
    int kind;        /* fi_kind_t */
    uint64_t start_tick;
    uint64_t end_tick;
    int32_t counts;
    double amp_nm;
} fi_fault_t;

#define FI_MAX_TICKS 400000u /* error log capacity (400 s at 1 kHz) */

typedef struct {
    hal_sim_t sim;
    hal_mock_t mock;
    hal_t hal;       /* what the firmware sees */
    hal_t sim_hal;   /* the simulated joint's own binding */
    hd_fw_t fw;
    hd_fw_config_t cfg;
    hd_sim_nominal_t nom;
    fi_fault_t fault;
    uint64_t tick;   /* index of the tick being run */
    uint64_t n_ticks;
    /* per tick (index = tick) */
    float err_nm[FI_MAX_TICKS];   /* filtered - truth; NaN when the sample was invalid */
    uint32_t faults[FI_MAX_TICKS];/* HD_FAULT_* raised on the tick (hd_fw_sample_t) */
    /* telemetry decoded from the frames sent (docs/design/firmware.md layout) */
    uint32_t telem_a, telem_b, heartbeats, acks;
    uint32_t telem_faults_or;     /* OR of TELEM_B.Faults over all frames */
    uint32_t hb_faults_or;        /* OR of HEARTBEAT.HbFaults */
    uint8_t last_ack[8];
    uint8_t last_seq;
    bool have_seq;
    uint32_t seq_gaps;            /* telemetry periods lost (sequence jumps) */
    uint8_t last_hb_calib_status;
    uint32_t last_hb_faults;
    /* invariant violations (the tests assert these are 0) */
    uint32_t bad_steps;           /* a call did not advance the tick counter by one */
    uint32_t non_finite;          /* ripple / velocity / valid torque not finite */
    uint32_t out_of_bounds;       /* a finite output beyond its physical bound */
    uint32_t invalid_unflagged;   /* an invalid sample without a fault flag */
    double max_abs_filtered_nm;
} fi_rig_t;

/* The base scenario: paper_156-like (ratio 100, 0 -> 156 rad/s in 0.5 s,
 * 3 N m load, motor orders 2 and 4, output order 1, 0.02 N m noise).
 * `extra` (may be NULL) is appended, e.g. a speed profile or duration. */
void fi_rig_init(fi_rig_t *r, const char *extra);

/* Runs n ticks (or until the scenario ends); returns ticks run. */
uint64_t fi_rig_run(fi_rig_t *r, uint64_t n);

/* Recovery: ticks from `from_tick` to the first tick t such that every tick
 * in [t, t + hold) has a valid sample with |filtered - truth| <= band_nm.
 * Returns -1 if it never happens within the recorded ticks. */
long fi_recovery_ticks(const fi_rig_t *r, uint64_t from_tick, double band_nm, uint64_t hold);

/* max |err| over valid ticks in [a, b); NaN if none. */
double fi_max_abs_err(const fi_rig_t *r, uint64_t a, uint64_t b);
/* RMS of err over valid ticks in [a, b). */
double fi_rms_err(const fi_rig_t *r, uint64_t a, uint64_t b);
/* OR of per-tick faults over [a, b). */
uint32_t fi_faults_in(const fi_rig_t *r, uint64_t a, uint64_t b);

/* Queues a command frame for node 1 (opcode, token, args). */
void fi_push_cmd(fi_rig_t *r, const uint8_t data[8], uint8_t len, uint8_t flags, uint32_t id);

/* The recovery band and hold used throughout (docs/results/reliability.md prints
 * them with the table, from fi_report_setup). */
#define FI_BAND_NM 0.15
#define FI_HOLD_TICKS 200u

/* The `measured:` lines (rel_measured.h) docs/results/reliability.md is written
 * from.  fi_report: one fault case: its recovery, the recovery limit the
 * test asserts, the worst |filtered - truth| over [err_from, err_to) (NaN:
 * none printed), the fault bits raised in [flag_from, flag_to), and `extra`
 * (more key=value pairs, may be NULL).  fi_report_setup: the rig's band,
 * hold and fault start tick. */
void fi_report(const fi_rig_t *r, const char *name, long recovery_ticks, long limit_ticks,
               double max_err_nm, uint64_t flag_from, uint64_t flag_to, const char *extra);
void fi_report_setup(uint64_t fault_start_tick);

#endif /* FI_RIG_H */
