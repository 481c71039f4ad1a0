/*
 * hdsim-campaign: a static calibration campaign on the simulated joint
 * (Taghirad 1997, section III), written as the calibration CSV
 * (docs/calibration.md).
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
 */
#include "hd_bridge.h"

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
    int spread_random;
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
        "  --spread FRACTION       std/mean of per-experiment gains (0)\n"
        "  --spread-random         draw the spread (default: scaled to exactly FRACTION)\n"
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
        "  --seed N                (1)     -o FILE (stdout)\n");
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

static int parse_args(int argc, char **argv, opts_t *o)
{
    for (int i = 1; i < argc; ++i) {
        const char *a = argv[i];
        if (!strcmp(a, "-h") || !strcmp(a, "--help")) {
            usage(stdout);
            exit(0);
        }
        if (!strcmp(a, "--spread-random")) {
            o->spread_random = 1;
            continue;
        }
        if (i + 1 >= argc) {
            fprintf(stderr, "hdsim-campaign: %s needs a value (or is unknown)\n", a);
            return -1;
        }
        const char *v = argv[++i];
        double d = 0.0;
        int is_out = !strcmp(a, "-o") || !strcmp(a, "--out");
        if (is_out) {
            o->out = v;
            continue;
        }
        if (parse_double(v, &d) != 0) {
            fprintf(stderr, "hdsim-campaign: %s: not a finite number: '%s'\n", a, v);
            return -1;
        }
        if (!strcmp(a, "--gain")) o->gain = d;
        else if (!strcmp(a, "--spread")) o->spread = d;
        else if (!strcmp(a, "--offset")) o->offset_v = d;
        else if (!strcmp(a, "--noise")) o->noise_v = d;
        else if (!strcmp(a, "--nonlinearity")) o->nonlin_pct = d;
        else if (!strcmp(a, "--hysteresis")) o->hyst_pct = d;
        else if (!strcmp(a, "--position-dep")) o->pos_pct = d;
        else if (!strcmp(a, "--position-phase")) o->pos_phase_deg = d;
        else if (!strcmp(a, "--placement-error")) o->placement_sd_rad = d;
        else if (!strcmp(a, "--full-scale")) o->full_scale_nm = d;
        else if (!strcmp(a, "--low-range")) o->low_range = d;
        else if (!strcmp(a, "--arm")) o->arm_m = d;
        else if (!strcmp(a, "--counts-per-volt")) o->counts_per_v = d;
        else if (!strcmp(a, "--experiments")) o->experiments = (int)d;
        else if (!strcmp(a, "--positions")) o->positions = (int)d;
        else if (!strcmp(a, "--levels")) o->levels = (int)d;
        else if (!strcmp(a, "--seed")) o->seed = (uint64_t)d;
        else {
            fprintf(stderr, "hdsim-campaign: unknown option %s\n", a);
            return -1;
        }
    }
    if (!(o->gain > 0) || o->spread < 0 || o->noise_v < 0 || o->nonlin_pct < 0 ||
        o->hyst_pct < 0 || o->pos_pct < 0 || o->placement_sd_rad < 0 ||
        !(o->full_scale_nm > 0) || !(o->low_range > 0 && o->low_range <= 1) ||
        !(o->arm_m > 0) || o->counts_per_v < 0) {
        fprintf(stderr, "hdsim-campaign: gain, full scale, arm must be > 0, low range in (0,1], "
                        "sizes and noise >= 0\n");
        return -1;
    }
    if (o->experiments < 1 || o->experiments > MAX_EXPERIMENTS || o->positions < 1 ||
        o->levels < 1 || o->levels > MAX_LEVELS) {
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
    opts_t o = {6.60, 0.0, 0.0, 0.002, 0, 0, 0, 0, 0.01, 60.0, 0.2, 0.5, 0.0, 0, 8, 4, 5, 1, NULL};
    if (parse_args(argc, argv, &o) != 0) {
        usage(stderr);
        return 2;
    }
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

    /* Per-experiment gain factors: standard normal draws, optionally rescaled
     * to sample mean 0 and sample sd 1 so the campaign's spread is exact. */
    double z[MAX_EXPERIMENTS];
    double zm = 0.0, zs = 0.0;
    for (int e = 0; e < o.experiments; ++e) {
        z[e] = nrand();
        zm += z[e];
    }
    zm /= o.experiments;
    for (int e = 0; e < o.experiments; ++e) {
        zs += (z[e] - zm) * (z[e] - zm);
    }
    zs = (o.experiments > 1) ? sqrt(zs / (o.experiments - 1)) : 1.0;
    if (!o.spread_random && o.experiments > 1 && zs > 0) {
        for (int e = 0; e < o.experiments; ++e) {
            z[e] = (z[e] - zm) / zs;
        }
    }

    hd_bridge_config_t bridge;
    hd_bridge_config_default(&bridge);
    for (int k = 0; k < HD_BRIDGE_ROSETTES; ++k) {
        bridge.placement_error_rad[k] = (float)(o.placement_sd_rad * nrand());
    }
    double v_per_strain = (double)bridge.gauge_factor * (double)bridge.supply_v * (double)bridge.amp_gain;

    FILE *f = stdout;
    if (o.out != NULL && (f = fopen(o.out, "w")) == NULL) {
        fprintf(stderr, "hdsim-campaign: cannot write %s: %s\n", o.out, strerror(errno));
        return 1;
    }
    fprintf(f, "# hdsim-campaign gain=%.6g spread=%.6g%s offset=%.6g noise=%.6g nonlinearity=%.6g "
               "hysteresis=%.6g position_dep=%.6g position_phase=%.6g placement_error=%.6g "
               "full_scale=%.6g low_range=%.6g arm=%.6g seed=%llu\n",
            o.gain, o.spread, o.spread_random ? "(random)" : "", o.offset_v, o.noise_v,
            o.nonlin_pct, o.hyst_pct, o.pos_pct, o.pos_phase_deg, o.placement_sd_rad,
            o.full_scale_nm, o.low_range, o.arm_m, (unsigned long long)o.seed);
    fprintf(f, "experiment,direction,position_deg,torque_nm,%s\n",
            o.counts_per_v > 0 ? "bridge_counts" : "bridge_v");
    for (int e = 0; e < o.experiments; ++e) {
        double pos_deg = (double)(e % o.positions) * 180.0 / o.positions;
        int low = e >= (o.experiments + 1) / 2 && o.experiments > 1;
        double fs = o.full_scale_nm * (low ? o.low_range : 1.0);
        /* Weights on the arm: each level adds one weight. */
        double weight_kg = fs / (o.levels * G_MPS2 * o.arm_m);
        double th = 2.0 * (pos_deg - o.pos_phase_deg) * PI / 180.0;
        double gain = o.gain * (1.0 + o.spread * z[e]) * (1.0 + o.pos_pct / 100.0 * cos(th));
        bridge.strain_per_nm = (float)(1.0 / (gain * v_per_strain));
        for (int i = 0; i < n; ++i) {
            double sgn = x[i] > 0 ? 1.0 : (x[i] < 0 ? -1.0 : 0.0);
            double torque = sgn * round(fabs(x[i]) * o.levels) * weight_kg * G_MPS2 * o.arm_m;
            double seen = torque + fs * (q_frac * x[i] * x[i] +
                          (unload[i] ? 0.5 : -0.5) * h_frac * sgn * (1.0 - x[i] * x[i]));
            double v = (double)hd_bridge_output_v(&bridge, (float)seen, (float)(pos_deg * PI / 180.0)) +
                       o.offset_v + o.noise_v * nrand();
            fprintf(f, "%d,%s,%.3f,%.6f,", e + 1, unload[i] ? "unload" : "load", pos_deg, torque);
            if (o.counts_per_v > 0) {
                fprintf(f, "%.0f\n", round(v * o.counts_per_v));
            } else {
                fprintf(f, "%.7f\n", v);
            }
        }
    }
    if (f != stdout && fclose(f) != 0) {
        fprintf(stderr, "hdsim-campaign: error writing %s\n", o.out);
        return 1;
    }
    return 0;
}
