/*
 * The tick's stages, each with the state it owns (tick context only; the
 * background reads the few fields named below).  hd_fw_isr (hd_fw_tick.c)
 * calls them in this order; each stage reads the sample the earlier ones
 * filled (hd_fw_sample_t) and fills its own part of it.
 *
 *   stage              file                state
 *   gauge              hd_fw_sense.c       hd_fw_gauge_t     ADC -> V -> N m, tare window
 *   encoder tracker    hd_fw_encoder.c     hd_fw_encoder_t   counts -> increments, positions
 *   current estimator  hd_fw_current.c     hd_fw_current_t   current channel; T_cur's low-pass
 *   feed-forward latch hd_fw_ff.c          hd_fw_ff_t        FEEDFORWARD frames, stale fallback
 *   expected torque    filter/hd_slow.c    (none of its own) T_exp and its variance, pure
 *   filter             hd_fw_filter.c      hd_fw_filter_t    profiles, hd_pipeline_sample, health
 *   control            hd_fw_control.c     hd_fw_ctrl_state_t (hd_fw.h) setpoints, reactions,
 *                                                            law, drive
 *   telemetry          hd_fw_publish.c     hd_fw_telem_t     boot, TELEM_A/B/C, heartbeat, ACKs
 *
 * Each stage function returns the fault bits (HD_FAULT_*) it raised.
 */
#ifndef HD_FW_STAGES_H
#define HD_FW_STAGES_H

#include <stdbool.h>
#include <stdint.h>

#include "hd_kf.h"
#include "hd_slow.h"

#define HD_FW_TARE_TICKS 64u /* tare averages the last this many valid samples */

/* Gauge.  The background's TARE reads tare_v[0 .. tare_n). */
typedef struct {
    float tare_v[HD_FW_TARE_TICKS]; /* the last valid bridge voltages */
    volatile uint32_t tare_n;
    uint32_t tare_next;
} hd_fw_gauge_t;

/* Encoder tracker.  Absolute angles: the first good count modulo cpr plus
 * every increment given to the filter, so they follow the filter's phase. */
typedef struct {
    bool have_prev;
    bool output_present;            /* the last good read had an output encoder */
    uint32_t prev_motor_counts;
    uint32_t prev_output_counts;
    int32_t last_good_motor_delta;
    int32_t last_good_output_delta;
    bool pos_valid;
    bool output_pos_valid;          /* an output encoder gave the output angle */
    uint32_t pos_motor_cpr;         /* the cprs the positions are counted in */
    uint32_t pos_output_cpr;
    uint32_t motor_pos;             /* [0, motor cpr) */
    uint32_t output_pos;            /* [0, output cpr) */
} hd_fw_encoder_t;

/* Current estimator: the last good reading and T_cur's low-pass. */
typedef struct {
    float current_a;
    hd_slow_current_t est;
} hd_fw_current_t;

/* Feed-forward latch (docs/design/slow-torque.md, "Feed-forward"). */
typedef struct {
    bool have;                      /* a frame was accepted since boot */
    uint8_t seq;                    /* of the last accepted frame */
    float nm;                       /* its value */
    uint32_t age_ticks;             /* ticks since it arrived (saturating) */
    uint32_t stale_ticks;           /* ticks stale (saturating) */
} hd_fw_ff_t;

/* Filter.  The background reads snapshot once snapshot_seq moved, and
 * waits while import_pending or snapshot_pending is set. */
typedef struct {
    bool import_pending;            /* take bg.profile before this tick's step */
    bool snapshot_pending;          /* export after this tick's step */
    hd_kf_profile_t snapshot;       /* PROFILE_SAVE: the filter at a tick boundary */
    volatile uint32_t snapshot_seq; /* incremented when snapshot is written */
} hd_fw_filter_t;

/* Telemetry scheduler. */
typedef struct {
    bool boot_sent;
    uint32_t countdown;             /* ticks to the next TELEM_A/B pair */
    uint8_t seq;
    uint32_t pairs;                 /* for TELEM_C's every-Nth */
    uint32_t faults;                /* faults since the last telemetry frame */
    uint8_t kf_status;
    uint32_t hb_faults;             /* faults since the last heartbeat */
    uint32_t hb_countdown;
} hd_fw_telem_t;

#endif /* HD_FW_STAGES_H */
