/*
 * bench_compute: host throughput of the filter update, side by side with the
 * dense double-precision reference (tests/filter/ref_kf_dense.c), a dense
 * float32 textbook filter (dense_kf_f32.c, Joseph form, agreeing with the
 * reference) and the step before issue 16 (kf_step_v0.c, the baseline of the
 * speed-up), all measured in one run on the same input.  Also prints the
 * state sizes per model capacity.  The step before issue 16 turned by the
 * increment passed with a sample after correcting with it (the filter now
 * turns first): on this constant-speed input its max|diff| is the two
 * orders' different first steps (the time update by the first increment,
 * Q added once more), fading as both converge, not an error.
 *
 *   bench_compute [--steps N] [--reps R] [--warmup W] [--json]
 *
 * Harness: for each model, every implementation gets a fresh filter, W
 * warm-up batches, then R timed batches of N steps each (CLOCK_MONOTONIC),
 * interleaved across implementations; the median batch gives ns per update
 * (min and max are printed too).  The filter state carries over between
 * batches, so the timed updates are steady-state ones.  This is a
 * benchmark: it prints numbers and never fails on speed.  Exit status 2 on a bad command line.
 */
#define _POSIX_C_SOURCE 199309L
#include <math.h>
#include <stdio.h>
#include <stdlib.h>
#include <string.h>
#include <time.h>

#include "bench_memory.h"
#include "dense_kf_f32.h"
#include "hd_kf.h"
#include "hd_pipeline.h"
#include "kf_step_v0.h"
#include "ref_kf_dense.h"

#define MAX_STEPS 100000
#define MAX_REPS 201
#define TS_S 0.001f
#define GEAR_RATIO 100.0
#define MOTOR_SPEED_RAD_S 156.0 /* the paper's demo speed */
#define NOISE_NM 0.02f

typedef enum {
    IMPL_HD_KF,
    IMPL_PIPELINE,
    IMPL_DENSE_F32,
    IMPL_DENSE_F64,
    IMPL_V0,
    IMPL_COUNT
} impl_t;

static const char *const IMPL_NAMES[IMPL_COUNT] = {
    "hd_kf_step", "hd_pipeline_step", "dense_f32", "dense_f64_ref", "hd_kf_step_v0"};

typedef struct {
    const char *name;
    int states;
    void (*make)(hd_kf_config_t *cfg);
} model_t;

/* Per-state q of the recommended tuning (noise 0.02 N m, settle 0.05 s), so
 * the covariance numbers are realistic (no denormals, no saturation). */
static float q_ripple(void)
{
    const float r = NOISE_NM * NOISE_NM;
    const float ratio = TS_S / 0.05f;
    return r * ratio * ratio;
}

static void make_paper4(hd_kf_config_t *cfg)
{
    hd_kf_config_paper(cfg, TS_S, false);
}

static void make_paper6(hd_kf_config_t *cfg)
{
    hd_kf_config_paper(cfg, TS_S, true);
}

static void make_recommended7(hd_kf_config_t *cfg)
{
    hd_kf_config_recommended(cfg, TS_S, NOISE_NM, 0.05f, 0.02f); /* firmware default */
}

static void make_eight(hd_kf_config_t *cfg)
{
    hd_kf_config_default(cfg, TS_S);
    cfg->r_nm2 = NOISE_NM * NOISE_NM;
    (void)hd_kf_config_add_block(cfg, HD_KF_LOCK_MOTOR, 2.0f, q_ripple());
    (void)hd_kf_config_add_block(cfg, HD_KF_LOCK_MOTOR, 4.0f, q_ripple());
    (void)hd_kf_config_add_block(cfg, HD_KF_LOCK_MOTOR, 6.0f, q_ripple());
    (void)hd_kf_config_add_block(cfg, HD_KF_LOCK_OUTPUT, 1.0f, q_ripple());
}

/* Every block the capacity allows, plus the offset state. */
static void make_max(hd_kf_config_t *cfg)
{
    hd_kf_config_default(cfg, TS_S);
    cfg->r_nm2 = NOISE_NM * NOISE_NM;
    cfg->offset_enabled = 1u;
    static const float motor_orders[] = {1.0f, 2.0f, 3.0f, 4.0f, 6.0f};
    for (size_t i = 0; i < sizeof motor_orders / sizeof motor_orders[0]; i++) {
        (void)hd_kf_config_add_block(cfg, HD_KF_LOCK_MOTOR, motor_orders[i], q_ripple());
    }
    (void)hd_kf_config_add_block(cfg, HD_KF_LOCK_OUTPUT, 1.0f, q_ripple());
    (void)hd_kf_config_add_block(cfg, HD_KF_LOCK_OUTPUT, 2.0f, q_ripple());
    /* distinct pickup lines: duplicated blocks would make an unobservable
     * pair whose split float32 rounding walks freely */
    for (float hz = 50.0f; cfg->block_count < HD_KF_MAX_BLOCKS; hz += 50.0f) {
        (void)hd_kf_config_add_block(cfg, HD_KF_LOCK_FIXED, hz, q_ripple());
    }
}

static const model_t MODELS[] = {
    {"paper 4th order (motor 2, 4)", 4, make_paper4},
    {"paper 6th order (+ output 1)", 6, make_paper6},
    {"recommended (6th + offset)", 7, make_recommended7},
    {"8 states (motor 2, 4, 6, output 1)", 8, make_eight},
    {"maximum (HD_KF_MAX_BLOCKS + offset)", HD_KF_MAX_STATES, make_max},
};
#define MODEL_COUNT (sizeof MODELS / sizeof MODELS[0])

/* Synthetic input: the paper's demo (156 rad/s, ripple 2x and 4x, misalignment,
 * noise from a fixed-seed LCG).  Same arrays for every implementation. */
static float g_torque_nm[MAX_STEPS];
static float g_dm_rad[MAX_STEPS];
static float g_do_rad[MAX_STEPS];

static double lcg_uniform(unsigned long long *s)
{
    *s = *s * 6364136223846793005ULL + 1442695040888963407ULL;
    return (double)(*s >> 11) / 9007199254740992.0;
}

static void make_input(int steps)
{
    unsigned long long seed = 156u;
    const double dm = MOTOR_SPEED_RAD_S * (double)TS_S;
    for (int k = 0; k < steps; k++) {
        const double th = dm * k;
        const double noise = ((lcg_uniform(&seed) - 0.5) * sqrt(12.0)) * (double)NOISE_NM;
        g_torque_nm[k] = (float)(3.0 + 1.0 * sin(2.0 * th + 0.3) + 0.4 * sin(4.0 * th + 1.1) +
                                 0.5 * sin(th / GEAR_RATIO - 0.7) + noise);
        g_dm_rad[k] = (float)dm;
        g_do_rad[k] = (float)(dm / GEAR_RATIO);
    }
}

static double now_ns(void)
{
    struct timespec ts;
    clock_gettime(CLOCK_MONOTONIC, &ts);
    return (double)ts.tv_sec * 1e9 + (double)ts.tv_nsec;
}

typedef struct {
    hd_kf_t kf;
    hd_pipeline_t pipe;
    dense_kf_f32_t d32;
    ref_kf_t d64;
    v0_kf_t v0;
} filters_t;

static filters_t g_f; /* static: ref_kf_t and the rest are a few KB */
static volatile float g_sink;

static int init_filters(impl_t impl, const hd_kf_config_t *cfg)
{
    switch (impl) {
    case IMPL_HD_KF:
        return hd_kf_init(&g_f.kf, cfg);
    case IMPL_PIPELINE: {
        hd_expected_config_t ex;
        hd_expected_config_default(&ex);
        return hd_pipeline_init(&g_f.pipe, cfg, &ex, 20.0f);
    }
    case IMPL_DENSE_F32:
        dense_kf_f32_init(&g_f.d32, cfg);
        return 0;
    case IMPL_V0:
        v0_kf_init(&g_f.v0, cfg);
        return 0;
    default:
        ref_kf_init(&g_f.d64, cfg);
        return 0;
    }
}

/* Runs steps updates; writes the filtered torque to out_nm if not NULL. */
static float run_batch(impl_t impl, int steps, float *out_nm)
{
    float acc = 0.0f;
    for (int k = 0; k < steps; k++) {
        const hd_kf_input_t in = {g_torque_nm[k], 0.0f, g_dm_rad[k], g_do_rad[k], 0.0f};
        float y;
        if (impl == IMPL_HD_KF) {
            hd_kf_output_t o;
            hd_kf_step(&g_f.kf, &in, &o);
            y = o.torque_filtered_nm;
        } else if (impl == IMPL_PIPELINE) {
            hd_kf_output_t o;
            hd_pipeline_step(&g_f.pipe, in.torque_meas_nm, in.d_motor_angle_rad,
                             in.d_output_angle_rad, 0.0f, 0.0f, &o);
            y = o.torque_filtered_nm;
        } else if (impl == IMPL_DENSE_F32) {
            dense_kf_f32_output_t o;
            dense_kf_f32_step(&g_f.d32, &in, &o);
            y = o.torque_filtered_nm;
        } else if (impl == IMPL_V0) {
            v0_kf_output_t o;
            v0_kf_step(&g_f.v0, &in, &o);
            y = o.torque_filtered_nm;
        } else {
            ref_kf_output_t o;
            ref_kf_step(&g_f.d64, &in, &o);
            y = (float)o.torque_filtered_nm;
        }
        if (out_nm != NULL) {
            out_nm[k] = y;
        }
        acc += y;
    }
    return acc;
}

static int cmp_double(const void *a, const void *b)
{
    const double x = *(const double *)a;
    const double y = *(const double *)b;
    return (x > y) - (x < y);
}

typedef struct {
    double median_ns, min_ns, max_ns;
    double max_diff_vs_f64_nm; /* agreement of the first batch with the f64 reference */
} result_t;

static float g_out[IMPL_COUNT][MAX_STEPS];

/* Times every implementation on one model.  Batches are interleaved
 * (rep r of each implementation runs back to back) so a load change on a
 * shared machine hits all implementations alike. */
static int measure_all(const hd_kf_config_t *cfg, int steps, int reps, int warmup,
                       result_t res[IMPL_COUNT])
{
    static double t[IMPL_COUNT][MAX_REPS];
    for (int i = 0; i < IMPL_COUNT; i++) {
        if (init_filters((impl_t)i, cfg) != 0) {
            return -1;
        }
        g_sink = run_batch((impl_t)i, steps, g_out[i]); /* first batch: kept for agreement */
    }
    for (int w = 1; w < warmup; w++) {
        for (int i = 0; i < IMPL_COUNT; i++) {
            g_sink = run_batch((impl_t)i, steps, NULL);
        }
    }
    for (int r = 0; r < reps; r++) {
        for (int i = 0; i < IMPL_COUNT; i++) {
            const double t0 = now_ns();
            g_sink = run_batch((impl_t)i, steps, NULL);
            t[i][r] = (now_ns() - t0) / steps;
        }
    }
    for (int i = 0; i < IMPL_COUNT; i++) {
        qsort(t[i], (size_t)reps, sizeof t[i][0], cmp_double);
        res[i].median_ns = t[i][reps / 2];
        res[i].min_ns = t[i][0];
        res[i].max_ns = t[i][reps - 1];
    }
    return 0;
}

static void usage(void)
{
    fprintf(stderr, "usage: bench_compute [--steps N (1..%d)] [--reps R (1..%d)] "
                    "[--warmup W (>=1)] [--json]\n", MAX_STEPS, MAX_REPS);
}

static int parse_int(const char *s, int lo, int hi, int *out)
{
    char *end = NULL;
    const long v = strtol(s, &end, 10);
    if (end == s || *end != '\0' || v < lo || v > hi) {
        return -1;
    }
    *out = (int)v;
    return 0;
}

static void print_memory(int json)
{
    bench_mem_sizes_t m[4];
    int i = 0;
#define BENCH_MEM_CALL(k) bench_mem_sizes_##k(&m[i++]);
    BENCH_MEM_CAPS(BENCH_MEM_CALL)
#undef BENCH_MEM_CALL
    if (json) {
        printf("  \"memory\": [\n");
        for (int j = 0; j < i; j++) {
            printf("    {\"capacity_blocks\": %d, \"capacity_states\": %d, \"hd_kf_bytes\": %zu, "
                   "\"pipeline_bytes\": %zu, \"dense_f32_bytes\": %zu, "
                   "\"dense_f32_stack_bytes\": %zu}%s\n",
                   m[j].capacity_blocks, m[j].capacity_states, m[j].hd_kf_bytes,
                   m[j].pipeline_bytes, m[j].dense_f32_bytes, m[j].dense_f32_stack_bytes,
                   j + 1 < i ? "," : "");
        }
        printf("  ]\n");
        return;
    }
    printf("\nState memory by compile-time capacity (bytes):\n");
    printf("%-16s %-16s %-10s %-14s %-10s %s\n", "HD_KF_MAX_BLOCKS", "max states", "hd_kf_t",
           "hd_pipeline_t", "dense_f32", "dense_f32 step stack (2 n x n)");
    for (int j = 0; j < i; j++) {
        printf("%-16d %-16d %-10zu %-14zu %-10zu %zu\n", m[j].capacity_blocks,
               m[j].capacity_states, m[j].hd_kf_bytes, m[j].pipeline_bytes, m[j].dense_f32_bytes,
               m[j].dense_f32_stack_bytes);
    }
}

int main(int argc, char **argv)
{
    int steps = 5000;
    int reps = 31;
    int warmup = 3;
    int json = 0;
    for (int a = 1; a < argc; a++) {
        int ok = 0;
        if (strcmp(argv[a], "--json") == 0) {
            json = 1;
            ok = 1;
        } else if (a + 1 < argc && strcmp(argv[a], "--steps") == 0) {
            ok = parse_int(argv[++a], 1, MAX_STEPS, &steps) == 0;
        } else if (a + 1 < argc && strcmp(argv[a], "--reps") == 0) {
            ok = parse_int(argv[++a], 1, MAX_REPS, &reps) == 0;
        } else if (a + 1 < argc && strcmp(argv[a], "--warmup") == 0) {
            ok = parse_int(argv[++a], 1, 1000, &warmup) == 0;
        }
        if (!ok) {
            usage();
            return 2;
        }
    }
    make_input(steps);

    if (json) {
        printf("{\n  \"steps\": %d, \"reps\": %d, \"warmup\": %d,\n  \"compute\": [\n", steps,
               reps, warmup);
    } else {
        printf("Host filter updates (%d steps x %d reps, %d warm-up batches, median):\n", steps,
               reps, warmup);
        printf("%-37s %-6s %-17s %12s %10s %10s %10s %16s\n", "model", "states", "implementation",
               "updates/s", "ns median", "ns min", "ns max", "max|diff f64| Nm");
    }
    for (size_t m = 0; m < MODEL_COUNT; m++) {
        hd_kf_config_t cfg;
        MODELS[m].make(&cfg);
        result_t res[IMPL_COUNT];
        if (measure_all(&cfg, steps, reps, warmup, res) != 0) {
            fprintf(stderr, "bench_compute: %s: bad configuration\n", MODELS[m].name);
            return 1;
        }
        for (int i = 0; i < IMPL_COUNT; i++) {
            double d = 0.0;
            for (int k = 0; k < steps; k++) {
                d = fmax(d, fabs((double)g_out[i][k] - (double)g_out[IMPL_DENSE_F64][k]));
            }
            res[i].max_diff_vs_f64_nm = d;
        }
        for (int i = 0; i < IMPL_COUNT; i++) {
            const double ratio = res[i].median_ns / res[IMPL_HD_KF].median_ns;
            if (json) {
                printf("    {\"model\": \"%s\", \"states\": %d, \"impl\": \"%s\", "
                       "\"updates_per_s\": %.0f, \"ns_median\": %.2f, \"ns_min\": %.2f, "
                       "\"ns_max\": %.2f, \"time_ratio_vs_hd_kf\": %.3f, "
                       "\"max_diff_vs_f64_nm\": %.3g}%s\n",
                       MODELS[m].name, MODELS[m].states, IMPL_NAMES[i], 1e9 / res[i].median_ns,
                       res[i].median_ns, res[i].min_ns, res[i].max_ns, ratio,
                       res[i].max_diff_vs_f64_nm,
                       (m + 1 < MODEL_COUNT || i + 1 < IMPL_COUNT) ? "," : "");
            } else {
                printf("%-37s %-6d %-17s %12.0f %10.1f %10.1f %10.1f %16.2e   (x%.2f time)\n",
                       MODELS[m].name, MODELS[m].states, IMPL_NAMES[i], 1e9 / res[i].median_ns,
                       res[i].median_ns, res[i].min_ns, res[i].max_ns, res[i].max_diff_vs_f64_nm,
                       ratio);
            }
        }
        if (!json) {
            printf("%-37s %-6d hd_kf_step is %.2f x faster than hd_kf_step_v0 and %.2f x faster "
                   "than dense_f32\n", "", MODELS[m].states,
                   res[IMPL_V0].median_ns / res[IMPL_HD_KF].median_ns,
                   res[IMPL_DENSE_F32].median_ns / res[IMPL_HD_KF].median_ns);
        }
    }
    if (json) {
        printf("  ],\n");
    }
    print_memory(json);
    if (json) {
        printf("}\n");
    }
    return 0;
}
