/*
 * hdjoint-host: runs the firmware ISR on a PC.
 *
 *   hdjoint-host --sensors sim:SCENARIO.ini | replay:FILE.hdraw | mock [options]
 *
 * (the options: host_options.c, `--help`; the NVM image and what is stored
 * before boot: host_nvm.c; the summary: host_report.c)
 *
 * Fast mode (default) runs ticks back to back; --realtime runs them at 1 kHz
 * on CLOCK_MONOTONIC with clock_nanosleep(TIMER_ABSTIME) and reports wake-up
 * jitter and overruns.  Prints a summary (key = value lines) at the end.
 *
 * Nothing is lost and nothing is silent (docs/results/reliability.md):
 * - the CSV and the CAN log are written under temporary names and renamed
 *   when the run ends; a failed write ends the run with one line on stderr
 *   and exit 3, and the old files stay as they were;
 * - the NVM image (--nvm) is written (temporary file, fsync, rename) at the
 *   start if the provisioning changed it and right after every change the
 *   firmware makes (CALIB_SAVE ...), not only at exit; a missing image file
 *   is created (erased) at the start, so an unwritable path fails at once;
 * - SIGINT / SIGTERM end the run after the current tick: outputs flushed
 *   and renamed with whole lines, summary printed, exit 128 + signal;
 * - every --cmd frame is handed to the firmware (as its receive queue has
 *   room: HD_FW_RX_PER_TICK per tick) or the run fails saying how many were
 *   not.
 *
 * Exit status: 0 ok; 1 run failed (SocketCAN, commands not delivered);
 * 2 bad command line or input file (configuration, scenario, replay, NVM
 * image); 3 an output could not be written; 130 / 143 interrupted by
 * SIGINT / SIGTERM (outputs whole up to the interruption).
 *
 * Host only: uses stdio, the heap, libm and double.
 */
#define _POSIX_C_SOURCE 200809L

#include <errno.h>
#include <math.h>
#include <signal.h>
#include <stdio.h>
#include <stdlib.h>
#include <string.h>
#include <time.h>

#include "hal_mock.h"
#include "hal_replay.h"
#include "hd_config_text.h"
#include "hd_fw.h"
#include "hd_fw_records.h"
#include "hd_hostio.h"
#include "host_nvm.h"
#include "host_options.h"
#include "host_report.h"
#ifdef HD_HAVE_SIM
#include "hal_sim.h"
#include "host_sim.h"
#endif
#ifdef HD_HAVE_SOCKETCAN
#include "hal_socketcan.h"
#endif

#define HOST_PI 3.14159265358979323846

/* A heap block that lives until exit, held by a global so that an early
 * return (an error message and exit) is not reported as a leak. */
static void *g_heap_cmd_frames;
static hal_replay_t *g_replay;

/* ------------------------------------------------------------ CAN logging */

typedef struct {
    hd_out_t out;
    bool open;
    uint64_t frames;
} canlog_t;

static void log_frame(void *ctx, const hal_can_frame_t *frame, uint64_t t_us)
{
    canlog_t *l = ctx;
    char line[200];
    if (!l->open || hd_out_failed(&l->out)) {
        return;
    }
    const int n = hal_candump_format(frame, t_us, "vcan0", line, sizeof line);
    if (n > 0 && hd_out_write(&l->out, line, (size_t)n) == 0) {
        l->frames++;
    }
}

/* ------------------------------------------------- synthetic joint (mock) */

/* A small deterministic joint for --sensors mock: motor at 156 rad/s,
 * true torque 5 sin(2 pi 0.5 t) Nm, ripple 1 Nm at motor order 2 and
 * 0.5 Nm at order 4, the paper's 6.60 Nm/V, 16-bit ADC over +-10 V. */
typedef struct {
    uint64_t k;
    double motor_angle_rad;
    double torque_true_nm;
} synth_t;

#define SYNTH_GAIN 6.60
#define SYNTH_VPC (10.0 / 32768.0)
#define SYNTH_CPR 4096u

static void synth_push(synth_t *s, hal_mock_t *m)
{
    double t = (double)s->k * 1e-3;
    double speed = 156.0;
    s->torque_true_nm = 5.0 * sin(2.0 * HOST_PI * 0.5 * t);
    double th = s->motor_angle_rad;
    double meas = s->torque_true_nm + 1.0 * sin(2.0 * th) + 0.5 * sin(4.0 * th + 0.3);
    double counts = meas / SYNTH_GAIN / SYNTH_VPC;
    uint32_t enc = (uint32_t)(int64_t)floor(th / (2.0 * HOST_PI) * SYNTH_CPR);
    hal_mock_sample_t smp;
    memset(&smp, 0, sizeof smp);
    smp.adc.bridge_counts = (int32_t)lround(counts);
    smp.enc.motor_counts = enc;
    hal_mock_push_sample(m, &smp);
    s->motor_angle_rad += speed * 1e-3;
    s->k++;
}

/* ---------------------------------------------------------------- timing */

static uint64_t now_ns(void)
{
    struct timespec ts;
    clock_gettime(CLOCK_MONOTONIC, &ts);
    return (uint64_t)ts.tv_sec * 1000000000ull + (uint64_t)ts.tv_nsec;
}

/* ------------------------------------------------------------------ main */

static hal_mock_t g_mock;  /* large: static storage, as on the MCU */
static hd_fw_t g_fw;

int main(int argc, char **argv)
{
    host_options_t o;
    int prc = host_parse_args(argc, argv, &o);
    if (prc != 0) {
        free(o.cmds);
        free(o.cmd_due);
        return prc > 0 ? 0 : EXIT_USAGE;
    }
    hd_hostio_catch_signals();
    char err[600] = "";
    hal_t hal;
    hal_mock_init(&g_mock);
    hal_mock_bind(&g_mock, &hal); /* NVM, clock, CAN (log) from the mock by default */
    g_mock.auto_advance_us = 0u;  /* the loop sets the time of each tick */
    hal.name = "host";

    hd_fw_config_t cfg;
    hd_fw_config_default(&cfg);

    /* sensors */
    enum { SRC_MOCK, SRC_SIM, SRC_REPLAY } src;
    hal_replay_t *replay = NULL;
    synth_t synth = {0};
#ifdef HD_HAVE_SIM
    hal_sim_t *sim = NULL;
    static hal_sim_t g_sim;
#endif
    bool have_truth = false;
    float default_gain = NAN, default_offset = NAN;
    if (strcmp(o.sensors, "mock") == 0) {
        src = SRC_MOCK;
        have_truth = true;
        default_gain = (float)SYNTH_GAIN;
        default_offset = 0.0f;
        cfg.motor_cpr = SYNTH_CPR;
        cfg.adc_volts_per_count = (float)SYNTH_VPC;
        if (o.duration_s < 0.0) {
            o.duration_s = 10.0;
        }
    } else if (strncmp(o.sensors, "replay:", 7) == 0) {
        src = SRC_REPLAY;
        /* hal_replay would block on a FIFO and read a directory as empty */
        if (hd_hostio_check_regular(o.sensors + 7, err, sizeof err) != 0) {
            fprintf(stderr, "hdjoint-host: %s\n", err);
            return EXIT_USAGE;
        }
        replay = hal_replay_open(o.sensors + 7, err, sizeof err);
        g_replay = replay;
        if (replay == NULL) {
            fprintf(stderr, "hdjoint-host: %s\n", err);
            return EXIT_USAGE;
        }
        if (hal_replay_ts_us(replay) != HD_FW_TS_US) {
            fprintf(stderr, "hdjoint-host: %s: sample period %u us, the firmware runs at %u us\n",
                    o.sensors + 7, hal_replay_ts_us(replay), HD_FW_TS_US);
            hal_replay_close(replay);
            return EXIT_USAGE;
        }
        hal_replay_bind(replay, &hal);
    } else if (strncmp(o.sensors, "sim:", 4) == 0) {
#ifdef HD_HAVE_SIM
        src = SRC_SIM;
        sim = &g_sim;
        if (hal_sim_open(sim, o.sensors + 4, err, sizeof err) != 0) {
            fprintf(stderr, "hdjoint-host: %s\n", err);
            return EXIT_USAGE;
        }
        hal_sim_bind(sim, &hal);
        have_truth = true;
        hd_sim_nominal_t nom;
        hal_sim_nominal(sim, &nom);
        if (nom.ts_s != 1e-3) {
            fprintf(stderr, "hdjoint-host: scenario sample period %g s, the firmware runs at 1 ms\n",
                    nom.ts_s);
            return EXIT_USAGE;
        }
        default_gain = (float)nom.gain_nm_per_v;
        default_offset = (float)nom.offset_v;
        host_sim_defaults(&nom, &cfg); /* the data sheet's, not the plant's model */
#else
        fprintf(stderr, "hdjoint-host: built without the simulated joint (hal/sim)\n");
        return EXIT_USAGE;
#endif
    } else {
        fprintf(stderr, "hdjoint-host: unknown --sensors %s (see --help)\n", o.sensors);
        return EXIT_USAGE;
    }

    /* configuration file on top of the defaults and the sensor's constants */
    if (o.config != NULL) {
        size_t len = 0;
        char *text = hd_hostio_read_file(o.config, HD_HOSTIO_TEXT_MAX_BYTES, &len, err, sizeof err);
        if (text == NULL) {
            fprintf(stderr, "hdjoint-host: %s\n", err);
            return EXIT_USAGE;
        }
        hd_cfgtxt_error_t ce;
        int rc = hd_config_text_parse(text, len, &cfg, &ce);
        free(text);
        if (rc != HD_FW_OK) {
            if (rc == HD_FW_ERR_DUPLICATE) {
                fprintf(stderr, "%s:%u: %s (first on line %u)\n", o.config, ce.line, ce.message,
                        ce.first_line);
            } else if (ce.line > 0u) {
                fprintf(stderr, "%s:%u: %s\n", o.config, ce.line, ce.message);
            } else {
                fprintf(stderr, "%s: %s\n", o.config, ce.message);
            }
            return EXIT_USAGE;
        }
    }

    /* frames given with --cmd, checked before anything is written */
    hal_can_frame_t *cmds = calloc((size_t)o.n_cmds + 1u, sizeof *cmds);
    g_heap_cmd_frames = cmds;
    if (cmds == NULL) {
        fprintf(stderr, "hdjoint-host: out of memory\n");
        return EXIT_RUN;
    }
    for (int i = 0; i < o.n_cmds; i++) {
        if (host_parse_frame(o.cmds[i], &cmds[i]) != 0) {
            fprintf(stderr, "hdjoint-host: bad --cmd %s (want ID#HEX as cansend: 3 or 8 id digits, up to 8 bytes)\n",
                    o.cmds[i]);
            return EXIT_USAGE;
        }
    }

    /* NVM: file image, then the requested or nominal calibration */
    nvm_file_t nvm = {0};
    nvm.path = o.nvm_file;
    if (host_nvm_load(&nvm, g_mock.nvm, err, sizeof err) != 0) {
        fprintf(stderr, "hdjoint-host: %s\n", err);
        return EXIT_USAGE;
    }
    if ((o.have_calib || (o.nvm_file == NULL && isfinite(default_gain))) &&
        host_provision_calibration(&hal, o.have_calib ? o.calib_gain : default_gain,
                              o.have_calib ? o.calib_offset : default_offset) != 0) {
        fprintf(stderr, "hdjoint-host: could not store the calibration record in NVM\n");
        return EXIT_RUN;
    }
    if (o.profile != NULL && host_provision_profile(&hal, o.profile, err, sizeof err) != 0) {
        fprintf(stderr, "hdjoint-host: %s\n", err);
        return EXIT_USAGE;
    }

    int rc = hd_fw_init(&g_fw, &hal, &cfg);
    if (rc != HD_FW_OK) {
        fprintf(stderr, "hdjoint-host: firmware init failed: %s\n", hd_fw_err_str(rc));
        return EXIT_USAGE;
    }
    if (host_nvm_sync(&nvm, g_mock.nvm, err, sizeof err) != 0) {
        fprintf(stderr, "hdjoint-host: %s\n", err);
        return EXIT_WRITE;
    }

    /* outputs: CAN log, CSV (temporary names until the end) */
    canlog_t canlog = {0};
    hd_out_t csv = {0};
    bool csv_open = false;
#ifdef HD_HAVE_SOCKETCAN
    hal_socketcan_t *sock = NULL;
#endif
    if (strncmp(o.can, "log:", 4) == 0) {
        if (hd_out_open(&canlog.out, o.can + 4, false, err, sizeof err) != 0) {
            fprintf(stderr, "hdjoint-host: %s\n", err);
            return EXIT_WRITE;
        }
        canlog.open = true;
        g_mock.tx_store = false; /* the log keeps them */
        g_mock.tx_hook = log_frame;
        g_mock.tx_hook_ctx = &canlog;
    } else if (strncmp(o.can, "socketcan:", 10) == 0) {
#ifdef HD_HAVE_SOCKETCAN
        /* The firmware narrows the filter to its node at init (set_rx_filter). */
        sock = hal_socketcan_open(o.can + 10, NULL, 0, false, err, sizeof err);
        if (sock == NULL) {
            fprintf(stderr, "hdjoint-host: %s\n", err);
            return EXIT_RUN;
        }
        memset(&hal.can, 0, sizeof hal.can);
        hal_socketcan_bind(sock, &hal.can);
#else
        fprintf(stderr, "hdjoint-host: built without SocketCAN support\n");
        return EXIT_USAGE;
#endif
    } else if (strcmp(o.can, "none") == 0) {
        g_mock.tx_store = false;
    } else {
        fprintf(stderr, "hdjoint-host: unknown --can %s (see --help)\n", o.can);
        return EXIT_USAGE;
    }
    if (o.csv != NULL) {
        if (hd_out_open(&csv, o.csv, false, err, sizeof err) != 0) {
            fprintf(stderr, "hdjoint-host: %s\n", err);
            hd_out_abort(&canlog.out);
            return EXIT_WRITE;
        }
        csv_open = true;
        hd_out_printf(&csv, "t_s,bridge_counts,torque_raw_nm,torque_filtered_nm,ripple_nm,"
                            "torque_expected_nm,motor_velocity_rad_s,motor_angle_rad,faults,"
                            "kf_status,torque_true_nm,feedforward_nm,motor_current_a\n");
    }

    uint64_t max_ticks = (o.duration_s > 0.0) ? (uint64_t)llround(o.duration_s * 1000.0) : UINT64_MAX;
    host_timing_t tm = {0};
    host_errors_t er = {0};
    double motor_angle = 0.0;
    uint64_t period_ns = (uint64_t)HD_FW_TS_US * 1000u;
    uint64_t next_ns = now_ns() + period_ns;
    uint64_t wall_start_ns = now_ns();
    uint64_t k = 0;
    int n_fed = 0;
    uint64_t ff_frames = 0u;
#ifdef HD_HAVE_SIM
    /* feed-forward frames come from the simulated controller unless the
     * bus is a real one */
    const bool inject_ff = strncmp(o.can, "socketcan:", 10) != 0;
    uint8_t ff_seq = 0u;
#endif
    bool nvm_failed = false;
    for (; k < max_ticks && hd_hostio_signal() == 0; k++) {
        if (o.realtime) {
            struct timespec ts = {(time_t)(next_ns / 1000000000ull), (long)(next_ns % 1000000000ull)};
            while (clock_nanosleep(CLOCK_MONOTONIC, TIMER_ABSTIME, &ts, NULL) == EINTR &&
                   hd_hostio_signal() == 0) {
            }
            if (hd_hostio_signal() != 0) {
                break;
            }
            uint64_t woke = now_ns();
            double late_us = (double)(woke - next_ns) / 1000.0;
            tm.jitter_sum_us += late_us;
            if (late_us > tm.jitter_max_us) {
                tm.jitter_max_us = late_us;
            }
        }
        if (src == SRC_MOCK) {
            synth_push(&synth, &g_mock);
        }
        g_mock.now_us = k * HD_FW_TS_US; /* time stamps of the CAN log: sample time */
        /* --cmd frames, in order, as the receive queue has room */
        while (n_fed < o.n_cmds && o.cmd_due[n_fed] <= k &&
               hal_mock_push_rx(&g_mock, &cmds[n_fed]) == HAL_OK) {
            log_frame(&canlog, &cmds[n_fed], g_mock.now_us);
            n_fed++;
        }
        uint64_t t0 = now_ns();
#ifdef HD_HAVE_SIM
        /* The simulated robot controller's feed-forward frame, from the
         * previous sample (one tick of latency, as on a bus). */
        if (src == SRC_SIM && inject_ff) {
            const hd_sim_sample_t *cur = hal_sim_current(sim);
            if (cur != NULL && cur->feedforward_sent) {
                hd_can_feedforward_t ffv = {(float)cur->feedforward_nm, ff_seq++};
                hal_can_frame_t ff;
                hd_can_encode_feedforward(cfg.node_id, &ffv, &ff);
                if (hal_mock_push_rx(&g_mock, &ff) == HAL_OK) {
                    log_frame(&canlog, &ff, g_mock.now_us);
                    ff_frames++;
                }
            }
        }
#endif
        hd_fw_isr(&g_fw);
        uint64_t t1 = now_ns();
        if (g_fw.tick.ended) {
            break;
        }
        double isr_us = (double)(t1 - t0) / 1000.0;
        tm.isr_sum_us += isr_us;
        if (isr_us > tm.isr_max_us) {
            tm.isr_max_us = isr_us;
        }
        tm.ticks++;
        if (hd_fw_background(&g_fw) && host_nvm_sync(&nvm, g_mock.nvm, err, sizeof err) != 0) {
            nvm_failed = true;
            break;
        }

        const hd_fw_sample_t *s = hd_fw_last_sample(&g_fw);
        double truth = NAN;
        if (src == SRC_MOCK) {
            truth = synth.torque_true_nm;
        }
#ifdef HD_HAVE_SIM
        if (src == SRC_SIM) {
            const hd_sim_sample_t *cur = hal_sim_current(sim);
            truth = (cur != NULL) ? cur->torque_true_nm : (double)NAN;
        }
#endif
        motor_angle += (double)s->d_motor_angle_rad;
        double t_s = (double)k * 1e-3;
        host_errors_add(&er, t_s, (double)s->torque_raw_nm, (double)s->torque_filtered_nm, truth);
        if (csv_open) {
            hd_out_printf(&csv, "%.3f,%d,%.6g,%.6g,%.6g,%.6g,%.6g,%.6f,%u,%u,%.6g", t_s,
                          (int)s->bridge_counts, (double)s->torque_raw_nm,
                          (double)s->torque_filtered_nm, (double)s->ripple_nm,
                          (double)s->torque_expected_nm, (double)s->motor_velocity_rad_s,
                          motor_angle, (unsigned)s->faults, (unsigned)s->kf_status, truth);
            hd_out_printf(&csv, ",%.6g,%.6g\n", (double)s->feedforward_nm,
                          (double)s->motor_current_a);
        }
        if ((csv_open && hd_out_failed(&csv)) || (canlog.open && hd_out_failed(&canlog.out))) {
            break; /* reported below, with the file and the reason */
        }
        if (o.realtime) {
            next_ns += period_ns;
            uint64_t now = now_ns();
            if (now > next_ns) {
                /* the deadline of the next tick has passed: skip whole periods */
                uint64_t behind = (now - next_ns) / period_ns + 1u;
                tm.overruns++;
                tm.missed_ticks += behind;
                next_ns += behind * period_ns;
                hd_fw_note_deadline_miss(&g_fw, (uint32_t)behind);
            }
        }
    }
    double wall_s = (double)(now_ns() - wall_start_ns) / 1e9;
    const int sig = hd_hostio_signal();
    free(cmds);
    free(o.cmds);
    free(o.cmd_due);

    /* the end: one error line and the old outputs, or whole new outputs */
    int exit_code = 0;
    if (nvm_failed) {
        fprintf(stderr, "hdjoint-host: %s\n", err);
        exit_code = EXIT_WRITE;
    } else if (sig == 0 && (n_fed < o.n_cmds || g_mock.rx_count != 0u)) {
        fprintf(stderr, "hdjoint-host: %u of %d --cmd frames not handled: the run ended after "
                "%llu ticks (%u frames per tick)\n", (unsigned)(o.n_cmds - n_fed) + g_mock.rx_count,
                o.n_cmds, (unsigned long long)tm.ticks, (unsigned)HD_FW_RX_PER_TICK);
        exit_code = EXIT_RUN;
    }
    hd_out_t *outs[2] = {csv_open ? &csv : NULL, canlog.open ? &canlog.out : NULL};
    if (exit_code == 0) {
        if (hd_out_commit_all(outs, 2u, err, sizeof err) != 0) {
            fprintf(stderr, "hdjoint-host: %s\n", err);
            exit_code = EXIT_WRITE;
        }
    }
    hd_out_abort(&csv);
    hd_out_abort(&canlog.out);
    if (exit_code != 0) {
        if (replay != NULL) {
            hal_replay_close(replay);
        }
#ifdef HD_HAVE_SOCKETCAN
        hal_socketcan_close(sock);
#endif
        return exit_code;
    }
    if (sig != 0) {
        fprintf(stderr, "hdjoint-host: interrupted by %s after %llu samples; outputs complete "
                "up to there\n", host_signal_name(sig), (unsigned long long)tm.ticks);
        exit_code = 128 + sig;
    }

    /* summary */
    if (!o.quiet) {
        const host_summary_t sum = {
            .o = &o, .fw = &g_fw, .hal = &hal, .tm = &tm, .er = &er, .wall_s = wall_s,
            .sig = sig, .have_truth = have_truth, .ff_frames = ff_frames,
            .canlog_open = canlog.open, .canlog_frames = canlog.frames, .nvm_writes = nvm.writes,
            .replay_trailing_bytes = replay != NULL ? hal_replay_trailing_bytes(replay) : 0u};
        host_print_summary(&sum);
    }
    if (replay != NULL) {
        hal_replay_close(replay);
    }
#ifdef HD_HAVE_SOCKETCAN
    hal_socketcan_close(sock);
#endif
    if (fflush(stdout) != 0 || ferror(stdout)) {
        fprintf(stderr, "hdjoint-host: stdout: write failed: %s\n", strerror(errno));
        return EXIT_WRITE;
    }
    return exit_code;
}
