/* host_report: what hdjoint-host measures during a run (tick timing, error
 * against the simulation's truth) and its key = value summary.  Host only. */
#ifndef HOST_REPORT_H
#define HOST_REPORT_H

#include <stdbool.h>
#include <stdint.h>

#include "hal.h"
#include "hd_fw.h"
#include "host_options.h"

typedef struct {
    uint64_t ticks;
    double jitter_max_us;
    double jitter_sum_us;
    uint64_t overruns;     /* ticks whose deadline had already passed */
    uint64_t missed_ticks; /* whole periods skipped to catch up */
    double isr_max_us;
    double isr_sum_us;
} host_timing_t;

/* RMS error sums of raw and filtered torque against the truth: the whole
 * run, the first second (boot) and after it. */
typedef struct {
    uint64_t n;
    double sum_raw2;
    double sum_filt2;
    uint64_t n_first;        /* the first second (boot) */
    double sum_filt2_first;
    uint64_t n_settled;      /* after the first second */
    double sum_raw2_settled;
    double sum_filt2_settled;
} host_errors_t;

/* Adds one sample (skipped if any value is not finite). */
void host_errors_add(host_errors_t *e, double t_s, double raw, double filt, double truth);

typedef struct {
    const host_options_t *o;
    const hd_fw_t *fw;
    const hal_t *hal;
    const host_timing_t *tm;
    const host_errors_t *er;
    double wall_s;
    int sig;                  /* the signal that ended the run, 0 if none */
    bool have_truth;
    uint64_t ff_frames;       /* feed-forward frames the simulated controller gave */
    bool canlog_open;
    uint64_t canlog_frames;
    uint32_t nvm_writes;
    unsigned replay_trailing_bytes;
} host_summary_t;

/* The summary on stdout (docs/results/reliability.md lists its keys). */
void host_print_summary(const host_summary_t *s);

const char *host_signal_name(int sig);

#endif
