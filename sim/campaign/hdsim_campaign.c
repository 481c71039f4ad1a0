/*
 * hdsim-campaign: a static calibration campaign on the simulated joint
 * (Taghirad 1997, section III), written as the calibration CSV
 * (docs/how-to/calibration.md).
 *
 * The wave generator is locked at a flexspline position; weights hung on an
 * arm apply torque = n * weight * g * arm, loading 0 -> +FS, unloading to 0,
 * loading to -FS, unloading to 0.  Experiments cycle through the positions;
 * the second half of the experiments uses the low range.  The bridge is the
 * rosette model of sim/hd_bridge.h (its placement errors make the
 * zero-torque output depend on position), then the injected imperfections:
 *   per-experiment gain spread, gain vs position (order 2), quadratic
 *   nonlinearity, hysteresis (loop closing at the turning points), offset,
 *   white noise, optional ADC quantisation.
 * Sizes are given the way the analysis reports them, so a test can compare
 * reported with injected directly.
 *
 * The per-experiment gain factors are independent normal draws,
 * gain_e = gain (1 + spread z_e): the campaign's sample spread is itself
 * random (for n experiments, (n-1) s^2 / (gain spread)^2 is chi-square with
 * n-1 degrees of freedom), as it is for a real sensor.  (Until 2026-11 the
 * draws were rescaled to exactly the requested spread, which made "the
 * analysis finds 2 %" a round trip.)
 *
 * Exit status (docs/results/reliability.md): 0 ok, 2 bad usage, 3 the output could
 * not be written (an existing file is left as it was).
 */
#include "hd_bridge.h"
#include "hd_hostio.h"

#include <errno.h>
#include <math.h>
#include <stdint.h>
#include <stdio.h>
#include <stdlib.h>
#include <string.h>

#define G_MPS2 9.80665
#define MAX_EXPERIMENTS 32
#define MAX_LEVELS 15
#define PI 3.14159265358979323846

typedef struct {
    double gain, spread, offset_v, noise_v;
    double nonlin_pct, hyst_pct, pos_pct, pos_phase_deg;
    double placement_sd_rad, full_scale_nm, low_range, arm_m, counts_per_v;
    int experiments, positions, levels;
    uint64_t seed;
    const char *out;
} opts_t;

static uint64_t g_state;

static double urand(void)
{
    g_state ^= g_state >> 12;
    g_state ^= g_state << 25;
    g_state ^= g_state >> 27;
    return (double)((g_state * 2685821657736338717ull) >> 11) * (1.0 / 9007199254740992.0);
}

static double nrand(void)
{
    double u1 = urand(), u2 = urand();
    if (u1 < 1e-300) {
        u1 = 1e-300;
    }
    return sqrt(-2.0 * log(u1)) * cos(2.0 * PI * u2);
}

static void usage(FILE *f)
{
    fprintf(f,
        "usage: hdsim-campaign [options]  (writes the calibration CSV)\n"
        "  --gain NM_PER_V         true sensor gain (6.60)\n"
        "  --spread FRACTION       std of the per-experiment gain factors, drawn (0)\n"
        "  --offset V              bridge offset added to the output (0)\n"
        "  --noise V               rms white noise on each reading (0.002)\n"
        "  --nonlinearity PCT      largest deviation from the best line, %% FS (0)\n"
        "  --hysteresis PCT        largest loading/unloading gap, %% FS (0)\n"
        "  --position-dep PCT      gain amplitude vs position (order 2), %% (0)\n"
        "  --position-phase DEG    flexspline position of the gain peak (0)\n"
        "  --placement-error RAD   rms rosette placement error (0.01)\n"
        "  --experiments N         (8)     --positions N (4)  --levels N (5)\n"
        "  --full-scale NM         (60)    --low-range FRACTION (0.2)  --arm M (0.5)\n"
        "  --counts-per-volt C     write bridge_counts instead of bridge_v\n"
        "  --seed N                (1)     -o FILE (stdout)\n"
        "  --version\n"
        "exit status: 0 ok, 2 bad usage, 3 output not written\n");
}

static int parse_double(const char *s, double *out)
{
    char *end;
    errno = 0;
    double v = strtod(s, &end);
    if (errno != 0 || end == s || *end != '\0' || !isfinite(v)) {
        return -1;
    }
    *out = v;
    return 0;
}

/* A decimal integer in [lo, hi], lo >= 0: digits only, no leading zero. */
static int parse_int(const char *s, long long lo, long long hi, long long *out)
{
    if (*s < '0' || *s > '9' || (s[0] == '0' && s[1] != '\0')) {
        return -1;
    }
    long long v = 0;
    for (const char *p = s; *p != '\0'; p++) {
        if (*p < '0' || *p > '9' || v > (hi - (*p - '0')) / 10) {
            return -1;
        }
        v = v * 10 + (*p - '0');
    }
    if (v < lo) {
        return -1;
    }
    *out = v;
    return 0;
}

typedef struct {
    const char *name;
    double *dst;
} dopt_t;

static int parse_args(int argc, char **argv, opts_t *o)
{
    const dopt_t dopts[] = {
        {"--gain", &o->gain}, {"--spread", &o->spread}, {"--offset", &o->offset_v},
        {"--noise", &o->noise_v}, {"--nonlinearity", &o->nonlin_pct},
        {"--hysteresis", &o->hyst_pct}, {"--position-dep", &o->pos_pct},
        {"--position-phase", &o->pos_phase_deg}, {"--placement-error", &o->placement_sd_rad},
        {"--full-scale", &o->full_scale_nm}, {"--low-range", &o->low_range},
        {"--arm", &o->arm_m}, {"--counts-per-volt", &o->counts_per_v},
    };
    for (int i = 1; i < argc; ++i) {
        const char *a = argv[i];
        if (!strcmp(a, "-h") || !strcmp(a, "--help")) {
            usage(stdout);
            exit(0);
        }
        if (!strcmp(a, "--version")) {
            printf("hdsim-campaign %s\n", hd_hostio_version());
            exit(0);
        }
        if (i + 1 >= argc) {
            fprintf(stderr, "hdsim-campaign: %s needs a value (or is unknown)\n", a);
            return -1;
        }
        const char *v = argv[++i];
        if (!strcmp(a, "-o") || !strcmp(a, "--out")) {
            o->out = v;
            continue;
        }
        long long iv = 0;
        if (!strcmp(a, "--experiments") || !strcmp(a, "--positions") || !strcmp(a, "--levels")) {
            if (parse_int(v, 1, 1000000, &iv) != 0) {
                fprintf(stderr, "hdsim-campaign: %s: not a whole number >= 1: '%s'\n", a, v);
                return -1;
            }
            *(!strcmp(a, "--experiments") ? &o->experiments
              : !strcmp(a, "--positions") ? &o->positions : &o->levels) = (int)iv;
            continue;
        }
        if (!strcmp(a, "--seed")) {
            if (parse_int(v, 0, INT64_MAX, &iv) != 0) {
                fprintf(stderr, "hdsim-campaign: --seed: not a decimal integer >= 0: '%s'\n", v);
                return -1;
            }
            o->seed = (uint64_t)iv;
            continue;
        }
        size_t k = 0;
        while (k < sizeof dopts / sizeof dopts[0] && strcmp(a, dopts[k].name) != 0) {
            k++;
        }
        if (k == sizeof dopts / sizeof dopts[0]) {
            fprintf(stderr, "hdsim-campaign: unknown option %s\n", a);
            return -1;
        }
        if (parse_double(v, dopts[k].dst) != 0) {
            fprintf(stderr, "hdsim-campaign: %s: not a finite number: '%s'\n", a, v);
            return -1;
        }
    }
    if (!(o->gain > 0) || o->spread < 0 || o->spread > 0.2 || o->noise_v < 0 ||
        o->nonlin_pct < 0 || o->hyst_pct < 0 || o->pos_pct < 0 || o->pos_pct >= 50 ||
        o->placement_sd_rad < 0 || !(o->full_scale_nm > 0) ||
        !(o->low_range > 0 && o->low_range <= 1) || !(o->arm_m > 0) || o->counts_per_v < 0) {
        fprintf(stderr, "hdsim-campaign: gain, full scale, arm must be > 0, low range in (0,1], "
                        "spread in [0, 0.2], position dependence in [0, 50) %%, "
                        "sizes and noise >= 0\n");
        return -1;
    }
    if (o->experiments > MAX_EXPERIMENTS || o->levels > MAX_LEVELS) {
        fprintf(stderr, "hdsim-campaign: experiments 1..%d, positions >= 1, levels 1..%d\n",
                MAX_EXPERIMENTS, MAX_LEVELS);
        return -1;
    }
    return 0;
}

/* One experiment's load schedule: normalised torque x and unloading flag. */
static int schedule(int levels, double *x, int *unload)
{
    int n = 0;
    for (int s = 1; s >= -1; s -= 2) {
        for (int k = (s == 1 ? 0 : 1); k <= levels; ++k) {
            x[n] = s * (double)k / levels;
            unload[n++] = 0;
        }
        for (int k = levels - 1; k >= 0; --k) {
            x[n] = s * (double)k / levels;
            unload[n++] = 1;
        }
    }
    return n;
}

int main(int argc, char **argv)
{
    opts_t o = {6.60, 0.0, 0.0, 0.002, 0, 0, 0, 0, 0.01, 60.0, 0.2, 0.5, 0.0, 8, 4, 5, 1, NULL};
    if (parse_args(argc, argv, &o) != 0) {
        return EXIT_USAGE; /* one line said what; --help has the rest */
    }
    hd_hostio_catch_signals();
    g_state = 0x9E3779B97F4A7C15ull ^ (o.seed * 0xD1B54A32D192ED03ull);
    if (g_state == 0) {
        g_state = 1;
    }
    double x[4 * MAX_LEVELS + 2];
    int unload[4 * MAX_LEVELS + 2];
    int n = schedule(o.levels, x, unload);

    /* Sizes as the analysis reports them: the quadratic q x^2 deviates from
     * its best line by q max(1 - m, m), m = mean x^2 over the points; the
     * branch gap h (1 - x^2) is largest at the smallest nonzero level. */
    double m = 0.0;
    for (int i = 0; i < n; ++i) {
        m += x[i] * x[i];
    }
    m /= n;
    double q_frac = (o.nonlin_pct / 100.0) / fmax(1.0 - m, m);
    double x1 = 1.0 / o.levels;
    double h_frac = (o.levels > 1) ? (o.hyst_pct / 100.0) / (1.0 - x1 * x1) : 0.0;

    /* Per-experiment gain factors: independent standard normal draws, used
     * as drawn (the spread of a campaign is a random quantity). */
    double z[MAX_EXPERIMENTS];
    for (int e = 0; e < o.experiments; ++e) {
        z[e] = nrand();
    }

    hd_bridge_config_t bridge;
    hd_bridge_config_default(&bridge);
    for (int k = 0; k < HD_BRIDGE_ROSETTES; ++k) {
        bridge.placement_error_rad[k] = (float)(o.placement_sd_rad * nrand());
    }
    double v_per_strain = (double)bridge.gauge_factor * (double)bridge.supply_v * (double)bridge.amp_gain;

    char err[512];
    hd_out_t out;
    if (hd_out_open(&out, o.out != NULL ? o.out : "-", false, err, sizeof err) != 0) {
        fprintf(stderr, "hdsim-campaign: %s\n", err);
        return EXIT_WRITE;
    }
    int ok = hd_out_printf(&out,
            "# hdsim-campaign gain=%.6g spread=%.6g offset=%.6g noise=%.6g nonlinearity=%.6g "
            "hysteresis=%.6g position_dep=%.6g position_phase=%.6g placement_error=%.6g "
            "full_scale=%.6g low_range=%.6g arm=%.6g seed=%llu\n",
            o.gain, o.spread, o.offset_v, o.noise_v, o.nonlin_pct, o.hyst_pct, o.pos_pct,
            o.pos_phase_deg, o.placement_sd_rad, o.full_scale_nm, o.low_range, o.arm_m,
            (unsigned long long)o.seed) == 0;
    ok = ok && hd_out_printf(&out, "experiment,direction,position_deg,torque_nm,%s\n",
                             o.counts_per_v > 0 ? "bridge_counts" : "bridge_v") == 0;
    for (int e = 0; ok && e < o.experiments; ++e) {
        double pos_deg = (double)(e % o.positions) * 180.0 / o.positions;
        int low = e >= (o.experiments + 1) / 2 && o.experiments > 1;
        double fs = o.full_scale_nm * (low ? o.low_range : 1.0);
        /* Weights on the arm: each level adds one weight. */
        double weight_kg = fs / (o.levels * G_MPS2 * o.arm_m);
        double th = 2.0 * (pos_deg - o.pos_phase_deg) * PI / 180.0;
        double gain = o.gain * (1.0 + o.spread * z[e]) * (1.0 + o.pos_pct / 100.0 * cos(th));
        bridge.strain_per_nm = (float)(1.0 / (gain * v_per_strain));
        for (int i = 0; ok && i < n; ++i) {
            double sgn = x[i] > 0 ? 1.0 : (x[i] < 0 ? -1.0 : 0.0);
            double torque = sgn * round(fabs(x[i]) * o.levels) * weight_kg * G_MPS2 * o.arm_m;
            double seen = torque + fs * (q_frac * x[i] * x[i] +
                          (unload[i] ? 0.5 : -0.5) * h_frac * sgn * (1.0 - x[i] * x[i]));
            double v = (double)hd_bridge_output_v(&bridge, (float)seen, (float)(pos_deg * PI / 180.0)) +
                       o.offset_v + o.noise_v * nrand();
            ok = hd_out_printf(&out, "%d,%s,%.3f,%.6f,", e + 1, unload[i] ? "unload" : "load",
                               pos_deg, torque) == 0;
            if (o.counts_per_v > 0) {
                ok = ok && hd_out_printf(&out, "%.0f\n", round(v * o.counts_per_v)) == 0;
            } else {
                ok = ok && hd_out_printf(&out, "%.7f\n", v) == 0;
            }
        }
        if (hd_hostio_signal() != 0) {
            fprintf(stderr, "hdsim-campaign: interrupted by signal %d: no output written\n",
                    hd_hostio_signal());
            hd_out_abort(&out);
            return 128 + hd_hostio_signal();
        }
    }
    if (hd_out_commit(&out, err, sizeof err) != 0) {
        fprintf(stderr, "hdsim-campaign: %s\n", err);
        return EXIT_WRITE;
    }
    return 0;
}
