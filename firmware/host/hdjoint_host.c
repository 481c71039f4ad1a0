/*
 * hdjoint-host: runs the firmware ISR on a PC.
 *
 *   hdjoint-host --sensors sim:SCENARIO.ini | replay:FILE.hdraw | mock
 *                [--can log:FILE.log | socketcan:IFNAME | none]
 *                [--config FILE] [--realtime] [--duration S] [--csv OUT.csv]
 *                [--calib GAIN_NM_PER_V,OFFSET_V] [--nvm FILE] [--cmd ID#HEX]...
 *
 * Fast mode (default) runs ticks back to back; --realtime runs them at 1 kHz
 * on CLOCK_MONOTONIC with clock_nanosleep(TIMER_ABSTIME) and reports wake-up
 * jitter and overruns.  Prints a summary (key = value lines) at the end.
 *
 * Nothing is lost and nothing is silent (docs/reliability.md):
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

#include <ctype.h>
#include <errno.h>
#include <getopt.h>
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
#ifdef HD_HAVE_SIM
#include "hal_sim.h"
#endif
#ifdef HD_HAVE_SOCKETCAN
#include "hal_socketcan.h"
#endif

#define EXIT_RUN 1
#define EXIT_USAGE 2
#define EXIT_WRITE 3

#define HOST_PI 3.14159265358979323846

/* --cmd-at times, held by a global like the other heap blocks of the
 * options (an early exit is not a leak). */
static uint64_t *g_heap_cmd_due;

/* "GAIN,OFFSET_V" -> two finite floats; strtof reports overflow (ERANGE),
 * which sscanf does not. */
static bool parse_calib_pair(const char *text, float *gain, float *offset_v)
{
    char *end;
    errno = 0;
    *gain = strtof(text, &end);
    if (end == text || *end != ',' || errno == ERANGE) {
        return false;
    }
    const char *second = end + 1;
    *offset_v = strtof(second, &end);
    return end != second && *end == '\0' && errno != ERANGE;
}

/* Heap blocks that live until exit, held by globals so that an early
 * return (an error message and exit) is not reported as a leak. */
static const char **g_heap_cmd_args;
static void *g_heap_cmd_frames;
static hal_replay_t *g_replay;

typedef struct {
    const char *sensors;
    const char *can;
    const char *config;
    const char *csv;
    const char *nvm_file;
    bool realtime;
    double duration_s;
    bool have_calib;
    float calib_gain;
    float calib_offset;
    const char **cmds;   /* argc entries at most */
    uint64_t *cmd_due;   /* tick from which each may be delivered (--cmd-at) */
    int n_cmds;
    bool quiet;
    const char *profile; /* profile record file to store in NVM before start */
} options_t;

static void usage(FILE *f)
{
    fputs("usage: hdjoint-host --sensors sim:SCENARIO | replay:FILE.hdraw | mock\n"
          "                    [--can log:FILE | socketcan:IFNAME | none] [--config FILE]\n"
          "                    [--realtime] [--duration S] [--csv OUT.csv]\n"
          "                    [--calib GAIN_NM_PER_V,OFFSET_V] [--nvm FILE] [--cmd ID#HEX]...\n"
          "                    [--profile FILE.hdprofile] [--quiet]\n"
          "       hdjoint-host --version | --help\n"
          "  -s, --sensors  sample source: the simulated joint, a recorded raw stream, or a\n"
          "                 built-in synthetic joint (mock)\n"
          "  --can          log: write every frame as a candump -l log; socketcan: use IFNAME\n"
          "  --config       firmware configuration text file (docs/firmware.md)\n"
          "  --realtime     run at a real 1 kHz (default: as fast as possible)\n"
          "  --duration     stop after S seconds of samples (default: end of the source; mock 10 s)\n"
          "  --csv          per-sample output\n"
          "  --calib        store this calibration record in NVM before start\n"
          "                 (sim: the scenario's nominal calibration is stored by default)\n"
          "  --nvm          NVM image file: loaded at start (if it exists), written after\n"
          "                 every change (temporary file, fsync, rename)\n"
          "  --cmd          command frame for the firmware, e.g. 01D01001#2100020000000000;\n"
          "                 repeatable, delivered in order from the first tick (log/none CAN)\n"
          "  --cmd-at       SECONDS:ID#HEX: the same, not before that sample time (in order\n"
          "                 with the --cmd frames)\n"
          "  --profile      store this profile record (hdsense profile) in NVM before start\n"
          "  -q, --quiet    no summary on stdout\n"
          "exit status: 0 ok, 1 run failed, 2 bad command line or input, 3 write failed,\n"
          "             130/143 interrupted by SIGINT/SIGTERM (outputs whole)\n",
          f);
}

static int bad_arg(const char *msg, const char *arg)
{
    fprintf(stderr, "hdjoint-host: %s%s%s (see --help)\n", msg, arg != NULL ? ": " : "",
            arg != NULL ? arg : "");
    return -1;
}

/* Returns 0 to run, 1 after --help/--version, -1 on a bad command line. */
static int parse_args(int argc, char **argv, options_t *o)
{
    static const struct option longopts[] = {
        {"sensors", required_argument, NULL, 's'},
        {"can", required_argument, NULL, 'c'},
        {"config", required_argument, NULL, 'f'},
        {"csv", required_argument, NULL, 'o'},
        {"nvm", required_argument, NULL, 'n'},
        {"duration", required_argument, NULL, 'd'},
        {"calib", required_argument, NULL, 'k'},
        {"cmd", required_argument, NULL, 'm'},
        {"cmd-at", required_argument, NULL, 'T'},
        {"realtime", no_argument, NULL, 'r'},
        {"quiet", no_argument, NULL, 'q'},
        {"profile", required_argument, NULL, 'P'},
        {"help", no_argument, NULL, 'h'},
        {"version", no_argument, NULL, 'V'},
        {NULL, 0, NULL, 0},
    };
    memset(o, 0, sizeof *o);
    o->can = "none";
    o->duration_s = -1.0;
    o->cmds = calloc((size_t)argc + 1u, sizeof *o->cmds);
    g_heap_cmd_args = o->cmds;
    if (o->cmds == NULL) {
        return bad_arg("out of memory", NULL);
    }
    o->cmd_due = calloc((size_t)argc + 1u, sizeof *o->cmd_due);
    g_heap_cmd_due = o->cmd_due;
    if (o->cmd_due == NULL) {
        return bad_arg("out of memory", NULL);
    }
    opterr = 0; /* our own one-line messages */
    int c;
    while ((c = getopt_long(argc, argv, ":s:qhV", longopts, NULL)) != -1) {
        char *end;
        switch (c) {
        case 's': o->sensors = optarg; break;
        case 'c': o->can = optarg; break;
        case 'f': o->config = optarg; break;
        case 'o': o->csv = optarg; break;
        case 'n': o->nvm_file = optarg; break;
        case 'r': o->realtime = true; break;
        case 'q': o->quiet = true; break;
        case 'P': o->profile = optarg; break;
        case 'm': o->cmds[o->n_cmds++] = optarg; break;
        case 'T': {
            errno = 0;
            double at = strtod(optarg, &end);
            if (end == optarg || *end != ':' || errno == ERANGE || !(at >= 0.0) || at > 1e7) {
                return bad_arg("--cmd-at wants SECONDS:ID#HEX with 0 <= SECONDS <= 1e7", optarg);
            }
            o->cmd_due[o->n_cmds] = (uint64_t)llround(at * 1000.0);
            o->cmds[o->n_cmds++] = end + 1;
            break;
        }
        case 'h':
            usage(stdout);
            return 1;
        case 'V':
            printf("hdjoint-host %s\n", hd_hostio_version());
            return 1;
        case 'd':
            errno = 0;
            o->duration_s = strtod(optarg, &end);
            if (end == optarg || *end != '\0' || errno == ERANGE || !(o->duration_s > 0.0) ||
                !isfinite(o->duration_s) || o->duration_s > 1e7) {
                return bad_arg("--duration must be a positive number of seconds (<= 1e7)",
                               optarg);
            }
            break;
        case 'k':
            if (!parse_calib_pair(optarg, &o->calib_gain, &o->calib_offset) ||
                !(o->calib_gain > 0.0f) || !isfinite(o->calib_gain) ||
                !isfinite(o->calib_offset)) {
                return bad_arg("--calib wants GAIN,OFFSET with GAIN > 0", optarg);
            }
            o->have_calib = true;
            break;
        case ':':
            return bad_arg("option needs a value", argv[optind - 1]);
        default:
            return bad_arg("unknown option", argv[optind - 1]);
        }
    }
    if (optind < argc) {
        return bad_arg("unexpected argument", argv[optind]);
    }
    if (o->sensors == NULL) {
        return bad_arg("--sensors is required", NULL);
    }
    if (o->n_cmds > 0 && strncmp(o->can, "socketcan:", 10) == 0) {
        return bad_arg("--cmd needs --can log:FILE or none (on SocketCAN, send commands on "
                       "the bus, e.g. with cansend)", NULL);
    }
    return 0;
}

/* "123#0011AA" -> frame (classic CAN, up to 8 bytes). */
static int hex_digit(char c)
{
    if (c >= '0' && c <= '9') return c - '0';
    if (c >= 'a' && c <= 'f') return c - 'a' + 10;
    if (c >= 'A' && c <= 'F') return c - 'A' + 10;
    return -1;
}

static int parse_frame(const char *s, hal_can_frame_t *f)
{
    memset(f, 0, sizeof *f);
    if (hex_digit(s[0]) < 0) {
        return -1; /* strtoul would skip spaces and take a sign */
    }
    char *end;
    errno = 0;
    unsigned long id = strtoul(s, &end, 16);
    /* cansend notation: 3 hex digits for 11 bits, 8 for 29 bits */
    const size_t digits = (size_t)(end - s);
    if (end == s || *end != '#' || errno == ERANGE || (digits != 3u && digits != 8u) ||
        (digits == 3u && id > 0x7FFu) || (digits == 8u && id > 0x1FFFFFFFu)) {
        return -1;
    }
    if (digits == 8u) {
        f->flags = HAL_CAN_FLAG_EXT;
    }
    const char *p = end + 1;
    size_t n = strlen(p);
    if (n % 2u != 0u || n / 2u > 8u) {
        return -1;
    }
    for (size_t i = 0; i < n / 2u; i++) {
        const int hi = hex_digit(p[2u * i]), lo = hex_digit(p[2u * i + 1u]);
        if (hi < 0 || lo < 0) {
            return -1;
        }
        f->data[i] = (uint8_t)(hi * 16 + lo);
    }
    f->id = (uint32_t)id;
    f->len = (uint8_t)(n / 2u);
    return 0;
}

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

static void synth_push(synth_t *s, hal_mock_t *m, hd_fw_config_t *cfg)
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
    (void)cfg;
}

/* ---------------------------------------------------------------- timing */

static uint64_t now_ns(void)
{
    struct timespec ts;
    clock_gettime(CLOCK_MONOTONIC, &ts);
    return (uint64_t)ts.tv_sec * 1000000000ull + (uint64_t)ts.tv_nsec;
}

typedef struct {
    uint64_t ticks;
    double jitter_max_us;
    double jitter_sum_us;
    uint64_t overruns;     /* ticks whose deadline had already passed */
    uint64_t missed_ticks; /* whole periods skipped to catch up */
    double isr_max_us;
    double isr_sum_us;
} timing_t;

/* ---------------------------------------------------------------- errors */

typedef struct {
    uint64_t n;
    double sum_raw2;
    double sum_filt2;
    uint64_t n_first;        /* the first second (boot) */
    double sum_filt2_first;
    uint64_t n_settled;      /* after the first second */
    double sum_raw2_settled;
    double sum_filt2_settled;
} err_t;

static void err_add(err_t *e, double t_s, double raw, double filt, double truth)
{
    if (!isfinite(raw) || !isfinite(filt) || !isfinite(truth)) {
        return;
    }
    double dr = raw - truth, df = filt - truth;
    e->n++;
    e->sum_raw2 += dr * dr;
    e->sum_filt2 += df * df;
    if (t_s < 1.0) {
        e->n_first++;
        e->sum_filt2_first += df * df;
    }
    if (t_s >= 1.0) {
        e->n_settled++;
        e->sum_raw2_settled += dr * dr;
        e->sum_filt2_settled += df * df;
    }
}

/* ------------------------------------------------------------------ NVM */

static int provision_calibration(hal_t *hal, float gain, float offset)
{
    hd_calib_record_t rec;
    hd_calib_record_default(&rec);
    rec.gain_nm_per_v = gain;
    rec.offset_v = offset;
    static uint8_t work[HD_STORE_IMAGE_MAX];
    const hd_calib_storage_t s = hd_fw_store_io(hal, work, sizeof work);
    return hd_calib_store_save(&s, &rec) == HD_RECORD_OK ? 0 : -1;
}

/* A profile record file (docs/slow-torque.md, "Record file"): "HDPF", u16
 * format version, u16 payload length, the payload of hd_fw_records.h, u32
 * CRC-32 of everything before it.  Stored as is: the firmware checks that
 * it is for this joint at boot (REFUSED otherwise, as on the MCU). */
static int provision_profile(hal_t *hal, const char *path, char *err, size_t err_len)
{
    size_t len = 0;
    char *buf = hd_hostio_read_file(path, 4096u, &len, err, err_len);
    if (buf == NULL) {
        return -1;
    }
    const uint8_t *b = (const uint8_t *)buf;
    int rc = -1;
    if (len < 12u || memcmp(b, "HDPF", 4) != 0) {
        snprintf(err, err_len, "%s: not a profile record file (no HDPF header)", path);
    } else if (hd_le_get_u16(b + 4) != HD_PROFILE_RECORD_VERSION) {
        snprintf(err, err_len, "%s: profile record format %u, this firmware reads %u", path,
                 (unsigned)hd_le_get_u16(b + 4), (unsigned)HD_PROFILE_RECORD_VERSION);
    } else if ((size_t)hd_le_get_u16(b + 6) + 12u != len ||
               hd_crc32(b, len - 4u) != hd_le_get_u32(b + len - 4u)) {
        snprintf(err, err_len, "%s: profile record file damaged (length or CRC)", path);
    } else {
        static uint8_t work[HD_STORE_IMAGE_MAX];
        const hd_store_io_t s = hd_fw_store_io(hal, work, sizeof work);
        rc = hd_store_save(&s, HD_RECORD_KIND_PROFILE, HD_PROFILE_RECORD_VERSION, b + 8,
                           len - 12u) == HD_RECORD_OK ? 0 : -1;
        if (rc != 0) {
            snprintf(err, err_len, "could not store the profile record in NVM");
        }
    }
    free(buf);
    return rc;
}

/* "fault_<name> = count" in the summary: the protocol's fault name, lower case. */
static void print_fault_count(unsigned bit, uint32_t count)
{
    const char *name = hd_can_fault_str(bit);
    printf("fault_");
    for (const char *c = name; *c != '\0'; c++) {
        putchar(tolower((unsigned char)*c));
    }
    printf(" = %u\n", (unsigned)count);
}

/* ------------------------------------------------------------------ NVM image */

typedef struct {
    const char *path;      /* NULL: no image file */
    uint8_t saved[HAL_MOCK_NVM_BYTES];
    bool missing;          /* no file yet: written at the start */
    uint32_t writes;
} nvm_file_t;

/* A missing file is an erased device; anything else must be a whole image. */
static int nvm_load(nvm_file_t *n, uint8_t *nvm, char *err, size_t err_len)
{
    memcpy(n->saved, nvm, sizeof n->saved);
    if (n->path == NULL) {
        return 0;
    }
    size_t len = 0;
    char *buf = hd_hostio_read_file(n->path, HAL_MOCK_NVM_BYTES, &len, err, err_len);
    if (buf == NULL) {
        if (errno == ENOENT && hd_hostio_check_regular(n->path, NULL, 0) != 0 &&
            strstr(err, "cannot open") != NULL) {
            n->missing = true; /* starts erased; written at once (an unwritable path fails now) */
            return 0;
        }
        return -1;
    }
    if (len != HAL_MOCK_NVM_BYTES) {
        snprintf(err, err_len, "%s: NVM image of %zu bytes, expected %u (not written by "
                 "hdjoint-host?)", n->path, len, (unsigned)HAL_MOCK_NVM_BYTES);
        free(buf);
        return -1;
    }
    memcpy(nvm, buf, HAL_MOCK_NVM_BYTES);
    memcpy(n->saved, buf, HAL_MOCK_NVM_BYTES);
    free(buf);
    return 0;
}

/* Writes the image if it changed since the last write (or load). */
static int nvm_sync(nvm_file_t *n, const uint8_t *nvm, char *err, size_t err_len)
{
    if (n->path == NULL || (!n->missing && memcmp(n->saved, nvm, sizeof n->saved) == 0)) {
        return 0;
    }
    if (hd_hostio_write_atomic(n->path, nvm, HAL_MOCK_NVM_BYTES, err, err_len) != 0) {
        return -1;
    }
    memcpy(n->saved, nvm, sizeof n->saved);
    n->missing = false;
    n->writes++;
    return 0;
}

/* ------------------------------------------------------------------ main */

static hal_mock_t g_mock;  /* large: static storage, as on the MCU */
static hd_fw_t g_fw;

static const char *signal_name(int sig)
{
    return sig == SIGINT ? "SIGINT" : (sig == SIGTERM ? "SIGTERM" : "a signal");
}

int main(int argc, char **argv)
{
    options_t o;
    int prc = parse_args(argc, argv, &o);
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
        cfg.adc_volts_per_count = (float)nom.adc_v_per_count;
        cfg.motor_cpr = nom.motor_cpr;
        if (nom.output_cpr != 0u) {
            cfg.output_cpr = nom.output_cpr;
        }
        cfg.gear_ratio = (float)nom.gear_ratio;
        /* No oracle (issue 12): the sensor's and encoders' constants are the
         * joint's data sheet; the expected-torque model (J, b, Fc) is NOT
         * the plant's: the firmware defaults (0) or what --config says. */
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
        if (parse_frame(o.cmds[i], &cmds[i]) != 0) {
            fprintf(stderr, "hdjoint-host: bad --cmd %s (want ID#HEX as cansend: 3 or 8 id digits, up to 8 bytes)\n",
                    o.cmds[i]);
            return EXIT_USAGE;
        }
    }

    /* NVM: file image, then the requested or nominal calibration */
    nvm_file_t nvm = {0};
    nvm.path = o.nvm_file;
    if (nvm_load(&nvm, g_mock.nvm, err, sizeof err) != 0) {
        fprintf(stderr, "hdjoint-host: %s\n", err);
        return EXIT_USAGE;
    }
    if ((o.have_calib || (o.nvm_file == NULL && isfinite(default_gain))) &&
        provision_calibration(&hal, o.have_calib ? o.calib_gain : default_gain,
                              o.have_calib ? o.calib_offset : default_offset) != 0) {
        fprintf(stderr, "hdjoint-host: could not store the calibration record in NVM\n");
        return EXIT_RUN;
    }
    if (o.profile != NULL && provision_profile(&hal, o.profile, err, sizeof err) != 0) {
        fprintf(stderr, "hdjoint-host: %s\n", err);
        return EXIT_USAGE;
    }

    int rc = hd_fw_init(&g_fw, &hal, &cfg);
    if (rc != HD_FW_OK) {
        fprintf(stderr, "hdjoint-host: firmware init failed: %s\n", hd_fw_err_str(rc));
        return EXIT_USAGE;
    }
    if (nvm_sync(&nvm, g_mock.nvm, err, sizeof err) != 0) {
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
    timing_t tm = {0};
    err_t er = {0};
    double motor_angle = 0.0;
    uint64_t period_ns = (uint64_t)HD_FW_TS_US * 1000u;
    uint64_t next_ns = now_ns() + period_ns;
    uint64_t wall_start_ns = now_ns();
    uint64_t k = 0;
    int n_fed = 0;
    /* feed-forward frames come from the simulated controller unless the
     * bus is a real one */
    const bool inject_ff = strncmp(o.can, "socketcan:", 10) != 0;
    uint8_t ff_seq = 0u;
    uint64_t ff_frames = 0u;
    (void)inject_ff;
    (void)ff_seq;
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
            synth_push(&synth, &g_mock, &cfg);
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
        if (hd_fw_background(&g_fw) && nvm_sync(&nvm, g_mock.nvm, err, sizeof err) != 0) {
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
        err_add(&er, t_s, (double)s->torque_raw_nm, (double)s->torque_filtered_nm, truth);
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
                "up to there\n", signal_name(sig), (unsigned long long)tm.ticks);
        exit_code = 128 + sig;
    }

    /* summary */
    const hd_fw_counters_t *c = hd_fw_counters(&g_fw);
    hal_counters_t hc = {0};
    if (hal.can.counters != NULL) {
        hal.can.counters(hal.can.ctx, &hc);
    }
    if (!o.quiet) {
        printf("samples = %llu\n", (unsigned long long)c->ticks);
        printf("valid_samples = %llu\n", (unsigned long long)c->valid_samples);
        printf("mode = %s\n", o.realtime ? "realtime" : "fast");
        if (sig != 0) {
            printf("interrupted = %s\n", signal_name(sig));
        }
        printf("wall_time_s = %.3f\n", wall_s);
        printf("isr_mean_us = %.3f\n", tm.ticks ? tm.isr_sum_us / (double)tm.ticks : 0.0);
        printf("isr_max_us = %.3f\n", tm.isr_max_us);
        if (o.realtime) {
            printf("jitter_mean_us = %.3f\n", tm.ticks ? tm.jitter_sum_us / (double)tm.ticks : 0.0);
            printf("jitter_max_us = %.3f\n", tm.jitter_max_us);
            printf("overruns = %llu\n", (unsigned long long)tm.overruns);
            printf("missed_ticks = %llu\n", (unsigned long long)tm.missed_ticks);
        }
        printf("deadline_misses = %u\n", (unsigned)c->deadline_misses);
        printf("fault_ticks = %u\n", (unsigned)c->fault_ticks);
        for (unsigned b = 0; b < HD_FAULT_COUNT; b++) {
            if (c->by_fault[b] != 0u) {
                print_fault_count(b, c->by_fault[b]);
            }
        }
        printf("calib_status = %d\n", hd_fw_record_status(&g_fw, HD_RECORD_KIND_CALIB));
        printf("profile_status = %d\n", hd_fw_record_status(&g_fw, HD_RECORD_KIND_PROFILE));
        printf("profile_imports = %u\n", (unsigned)c->profile_imports);
        const hd_fw_config_t *fc = hd_fw_config(&g_fw);
        printf("expected_model = J %g kg m^2, b %g N m s/rad, Fc %g N m (%s)\n",
               (double)fc->expected.inertia_kgm2, (double)fc->expected.viscous_nm_s_rad,
               (double)fc->expected.coulomb_nm, o.config != NULL ? "defaults + --config" :
               "defaults");
        printf("feedforward_frames_given = %llu\n", (unsigned long long)ff_frames);
        printf("feedforward_frames_taken = %u\n", (unsigned)c->feedforward_frames);
        printf("config_status = %d\n", hd_fw_record_status(&g_fw, HD_RECORD_KIND_CONFIG));
        printf("truth = %s\n", have_truth ? "yes" : "no");
        printf("telemetry_periods = %u\n", (unsigned)c->telemetry_frames);
        printf("commands = %u\n", (unsigned)c->commands);
        printf("command_errors = %u\n", (unsigned)c->command_errors);
        printf("cmd_frames_given = %d\n", o.n_cmds);
        printf("can_tx_ok = %u\n", (unsigned)hc.can_tx_ok);
        printf("can_tx_dropped = %u\n", (unsigned)hc.can_tx_dropped);
        if (canlog.open) {
            printf("can_log = %s\n", o.can + 4);
            printf("can_log_frames = %llu\n", (unsigned long long)canlog.frames);
        }
        if (o.nvm_file != NULL) {
            printf("nvm_file = %s\n", o.nvm_file);
            printf("nvm_writes = %u\n", (unsigned)nvm.writes);
        }
        if (er.n > 0u) {
            printf("rms_error_raw_nm = %.4f\n", sqrt(er.sum_raw2 / (double)er.n));
            printf("rms_error_filtered_nm = %.4f\n", sqrt(er.sum_filt2 / (double)er.n));
        }
        if (er.n_first > 0u) {
            printf("rms_error_filtered_first_1s_nm = %.4f\n",
                   sqrt(er.sum_filt2_first / (double)er.n_first));
        }
        if (er.n_settled > 0u) {
            printf("rms_error_raw_after_1s_nm = %.4f\n", sqrt(er.sum_raw2_settled / (double)er.n_settled));
            printf("rms_error_filtered_after_1s_nm = %.4f\n",
                   sqrt(er.sum_filt2_settled / (double)er.n_settled));
        }
        if (replay != NULL && hal_replay_trailing_bytes(replay) != 0u) {
            printf("replay_trailing_bytes = %u\n", hal_replay_trailing_bytes(replay));
        }
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
