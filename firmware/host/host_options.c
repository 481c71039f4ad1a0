#define _POSIX_C_SOURCE 200809L

#include "host_options.h"

#include <errno.h>
#include <getopt.h>
#include <math.h>
#include <stdio.h>
#include <stdlib.h>
#include <string.h>

#include "hd_hostio.h"

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

/* The options' heap blocks (--cmd texts, --cmd-at times) live until exit,
 * held by globals so that an early exit is not reported as a leak. */
static const char **g_heap_cmd_args;
static uint64_t *g_heap_cmd_due;

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
          "  --config       firmware configuration text file (docs/design/firmware.md)\n"
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

int host_parse_args(int argc, char **argv, host_options_t *o)
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

static int hex_digit(char c)
{
    if (c >= '0' && c <= '9') return c - '0';
    if (c >= 'a' && c <= 'f') return c - 'a' + 10;
    if (c >= 'A' && c <= 'F') return c - 'A' + 10;
    return -1;
}

int host_parse_frame(const char *s, hal_can_frame_t *f)
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
