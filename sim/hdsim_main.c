/*
 * hdsim: run a scenario of the simulated joint and write its samples.
 *
 *   hdsim SCENARIO.ini [--duration S] [--seed N] [--set KEY=VALUE]...
 *         --csv OUT.csv [--raw OUT.hdraw] [--nominal]
 *
 * OUT.csv ("-" = stdout) holds the measured signals and the ground truth;
 * OUT.hdraw is the raw sample stream of docs/reference/raw-stream.md.  --nominal
 * prints the nominal calibration as key=value lines on stdout (with no
 * --csv, it is all that runs).  Outputs are written under temporary names
 * and renamed when complete (sim/hd_hostio.h): an error or an interrupt
 * leaves the old files as they were.
 *
 * Exit status (docs/results/reliability.md): 0 ok, 2 bad usage or a bad scenario,
 * 3 an output could not be written, 128 + signal when interrupted by
 * SIGINT/SIGTERM (no output written).
 */
#include <errno.h>
#include <stdio.h>
#include <stdlib.h>
#include <string.h>

#include "hd_hostio.h"
#include "hd_sim_plant.h"
#include "hd_sim_scenario.h"

#define MAX_SETS 64

static void usage(FILE *f)
{
    fprintf(f,
            "usage: hdsim SCENARIO.ini [--duration S] [--seed N] [--set KEY=VALUE]...\n"
            "             --csv OUT.csv [--raw OUT.hdraw] [--nominal]\n"
            "       hdsim --version\n"
            "  --csv -   writes the CSV to stdout; keys are those of docs/reference/sim.md\n"
            "exit status: 0 ok, 2 bad usage or scenario, 3 write failed, 130/143 interrupted\n");
}

static void put_u16(unsigned char *b, unsigned v)
{
    b[0] = (unsigned char)(v & 0xFFu);
    b[1] = (unsigned char)((v >> 8) & 0xFFu);
}

static void put_u32(unsigned char *b, uint32_t v)
{
    for (int i = 0; i < 4; i++) {
        b[i] = (unsigned char)((v >> (8 * i)) & 0xFFu);
    }
}

static int write_raw_header(hd_out_t *f, uint32_t ts_us)
{
    unsigned char h[16] = {'H', 'D', 'R', 'W'};
    put_u16(h + 4, 1u);
    put_u16(h + 6, 16u);
    put_u32(h + 8, ts_us);
    put_u32(h + 12, 0u);
    return hd_out_write(f, h, sizeof(h));
}

static int write_raw_record(hd_out_t *f, const hd_sim_sample_t *s)
{
    unsigned char r[16];
    put_u32(r, (uint32_t)s->bridge_counts); /* two's complement i32 */
    put_u32(r + 4, s->motor_counts);
    put_u32(r + 8, s->output_counts);
    unsigned flags = (s->saturated ? 1u : 0u) | (s->encoder_fault ? 2u : 0u) |
                     (s->has_output ? 4u : 0u);
    put_u16(r + 12, flags);
    put_u16(r + 14, 0u);
    return hd_out_write(f, r, sizeof(r));
}

static int print_nominal(FILE *f, const hd_sim_nominal_t *n)
{
    return fprintf(f, "gain_nm_per_v=%.9g\noffset_v=%.9g\nadc_v_per_count=%.9g\nadc_bits=%d\n"
               "gear_ratio=%.9g\nmotor_cpr=%u\noutput_cpr=%u\nts_s=%.9g\n"
               "load_inertia_kgm2=%.9g\nviscous_nm_s_rad=%.9g\ncoulomb_nm=%.9g\n"
               "motor_kt_nm_per_a=%.9g\n",
            n->gain_nm_per_v, n->offset_v, n->adc_v_per_count, n->adc_bits, n->gear_ratio,
            (unsigned)n->motor_cpr, (unsigned)n->output_cpr, n->ts_s, n->load_inertia_kgm2,
            n->viscous_nm_s_rad, n->coulomb_nm, n->motor_kt_nm_per_a) < 0 ? -1 : 0;
}

static int need_arg(int i, int argc, const char *opt)
{
    if (i + 1 >= argc) {
        fprintf(stderr, "hdsim: %s needs a value\n", opt);
        return -1;
    }
    return 0;
}

int main(int argc, char **argv)
{
    const char *scenario = NULL, *csv_path = NULL, *raw_path = NULL;
    const char *duration = NULL, *seed = NULL;
    const char *sets[MAX_SETS];
    int n_sets = 0, nominal = 0;
    for (int i = 1; i < argc; i++) {
        const char *a = argv[i];
        if (strcmp(a, "-h") == 0 || strcmp(a, "--help") == 0) {
            usage(stdout);
            return 0;
        } else if (strcmp(a, "--version") == 0) {
            printf("hdsim %s\n", hd_hostio_version());
            return 0;
        } else if (strcmp(a, "--csv") == 0 || strcmp(a, "--raw") == 0 ||
                   strcmp(a, "--duration") == 0 || strcmp(a, "--seed") == 0 ||
                   strcmp(a, "--set") == 0) {
            if (need_arg(i, argc, a) != 0) {
                return EXIT_USAGE;
            }
            const char *v = argv[++i];
            if (strcmp(a, "--csv") == 0) {
                csv_path = v;
            } else if (strcmp(a, "--raw") == 0) {
                raw_path = v;
            } else if (strcmp(a, "--duration") == 0) {
                duration = v;
            } else if (strcmp(a, "--seed") == 0) {
                seed = v;
            } else if (n_sets < MAX_SETS) {
                sets[n_sets++] = v;
            } else {
                fprintf(stderr, "hdsim: more than %d --set options\n", MAX_SETS);
                return EXIT_USAGE;
            }
        } else if (strcmp(a, "--nominal") == 0) {
            nominal = 1;
        } else if (a[0] == '-' && a[1] != '\0') {
            fprintf(stderr, "hdsim: unknown option %s (see --help)\n", a);
            return EXIT_USAGE;
        } else if (scenario == NULL) {
            scenario = a;
        } else {
            fprintf(stderr, "hdsim: more than one scenario given (%s, %s)\n", scenario, a);
            return EXIT_USAGE;
        }
    }
    if (scenario == NULL || (csv_path == NULL && !nominal)) {
        fprintf(stderr, "hdsim: need a scenario file and --csv OUT.csv (see --help)\n");
        return EXIT_USAGE;
    }

    char err[512];
    hd_sim_scenario_t sc;
    hd_sim_scenario_default(&sc);
    if (hd_sim_scenario_load(&sc, scenario, err, sizeof(err)) != 0) {
        fprintf(stderr, "hdsim: %s\n", err);
        return EXIT_USAGE;
    }
    if ((duration != NULL && hd_sim_scenario_set(&sc, "duration_s", duration, err, sizeof(err)) != 0) ||
        (seed != NULL && hd_sim_scenario_set(&sc, "seed", seed, err, sizeof(err)) != 0)) {
        fprintf(stderr, "hdsim: command line: %s\n", err);
        return EXIT_USAGE;
    }
    for (int i = 0; i < n_sets; i++) {
        char kv[1024];
        if (strlen(sets[i]) >= sizeof(kv)) {
            fprintf(stderr, "hdsim: --set: longer than %zu characters\n", sizeof(kv) - 1u);
            return EXIT_USAGE;
        }
        snprintf(kv, sizeof(kv), "%s", sets[i]);
        char *eq = strchr(kv, '=');
        if (eq == NULL) {
            fprintf(stderr, "hdsim: --set %s: expected KEY=VALUE\n", sets[i]);
            return EXIT_USAGE;
        }
        *eq = '\0';
        if (hd_sim_scenario_set(&sc, kv, eq + 1, err, sizeof(err)) != 0) {
            fprintf(stderr, "hdsim: --set: %s\n", err);
            return EXIT_USAGE;
        }
    }
    hd_sim_plant_t *plant = malloc(sizeof(*plant));
    if (plant == NULL) {
        fprintf(stderr, "hdsim: out of memory\n");
        return EXIT_RUN;
    }
    if (hd_sim_plant_init(plant, &sc, err, sizeof(err)) != 0) {
        fprintf(stderr, "hdsim: %s: %s\n", scenario, err);
        free(plant);
        return EXIT_USAGE;
    }
    if (nominal) {
        if (print_nominal(stdout, &plant->nominal) != 0 || fflush(stdout) != 0) {
            fprintf(stderr, "hdsim: stdout: write failed: %s\n", strerror(errno));
            free(plant);
            return EXIT_WRITE;
        }
        if (csv_path == NULL) {
            free(plant);
            return 0;
        }
    }

    hd_hostio_catch_signals();
    hd_out_t csv, raw;
    memset(&raw, 0, sizeof raw);
    if (hd_out_open(&csv, csv_path, false, err, sizeof(err)) != 0) {
        fprintf(stderr, "hdsim: %s\n", err);
        free(plant);
        return EXIT_WRITE;
    }
    if (raw_path != NULL && hd_out_open(&raw, raw_path, false, err, sizeof(err)) != 0) {
        fprintf(stderr, "hdsim: %s\n", err);
        hd_out_abort(&csv);
        free(plant);
        return EXIT_WRITE;
    }
    /* The controller's feed-forward and the motor current exist only in
     * scenarios that have them (the analysis contract's optional columns). */
    const bool ff = sc.ff.enabled != 0, cur = sc.motor.kt_nm_per_a > 0.0;
    /* The slow external torque as truth (for "fraction of the load kept"),
     * in scenarios with gravity or sinusoidal loads. */
    const bool slow = sc.gravity.n > 0 || sc.load_sine_count > 0;
    int ok = hd_out_printf(&csv, "t_s,motor_angle_rad,output_angle_rad,motor_velocity_rad_s,"
                                 "output_velocity_rad_s,torque_nm,torque_true_nm,ripple_true_nm,"
                                 "bridge_counts,motor_counts,output_counts%s%s%s\n",
                           ff ? ",torque_feedforward_nm" : "", cur ? ",motor_current_a" : "",
                           slow ? ",load_torque_nm,gravity_nm" : "") == 0;
    if (ok && raw_path != NULL) {
        ok = write_raw_header(&raw, (uint32_t)(sc.ts_s * 1e6 + 0.5)) == 0;
    }
    hd_sim_sample_t s;
    uint64_t n = 0, saturated = 0;
    while (ok && hd_hostio_signal() == 0 && hd_sim_plant_next(plant, &s) == 0) {
        ok = hd_out_printf(&csv, "%.6f,%.9g,%.9g,%.9g,%.9g,%.7g,%.7g,%.7g,%ld,%lu,%lu", s.t_s,
                           s.motor_angle_rad, s.output_angle_rad, s.motor_velocity_rad_s,
                           s.output_velocity_rad_s, s.torque_nm, s.torque_true_nm,
                           s.ripple_true_nm, (long)s.bridge_counts,
                           (unsigned long)s.motor_counts, (unsigned long)s.output_counts) == 0;
        if (ok && ff) {
            ok = hd_out_printf(&csv, ",%.7g", s.feedforward_nm) == 0;
        }
        if (ok && cur) {
            ok = hd_out_printf(&csv, ",%.7g", s.motor_current_a) == 0;
        }
        if (ok && slow) {
            ok = hd_out_printf(&csv, ",%.7g,%.7g", s.load_torque_nm, s.gravity_nm) == 0;
        }
        if (ok) {
            ok = hd_out_printf(&csv, "\n") == 0;
        }
        if (ok && raw_path != NULL) {
            ok = write_raw_record(&raw, &s) == 0;
        }
        n++;
        saturated += s.saturated ? 1u : 0u;
    }
    const int sig = hd_hostio_signal();
    int rc = 0;
    if (sig != 0) {
        fprintf(stderr, "hdsim: interrupted by signal %d: no output written\n", sig);
        rc = 128 + sig;
    } else if (!ok) {
        /* the first failed write: commit reports it with its errno */
        rc = EXIT_WRITE;
    }
    if (rc == 0 || rc == EXIT_WRITE) {
        hd_out_t *outs[2] = {&csv, raw_path != NULL ? &raw : NULL};
        if (hd_out_commit_all(outs, 2u, err, sizeof(err)) != 0) {
            fprintf(stderr, "hdsim: %s\n", err);
            rc = EXIT_WRITE;
        }
    }
    hd_out_abort(&raw);
    hd_out_abort(&csv);
    if (rc == 0) {
        fprintf(stderr, "hdsim: %llu samples at %g s, nominal gain %.6g N m/V, %llu saturated\n",
                (unsigned long long)n, sc.ts_s, plant->nominal.gain_nm_per_v,
                (unsigned long long)saturated);
    }
    free(plant);
    return rc;
}
