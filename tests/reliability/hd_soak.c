/*
 * hd_soak: long-run numerics of the filter pipeline in float32.
 *
 *   hd_soak [STEPS] [--check-every K] [--seed S]
 *
 * Runs STEPS (default 10^6) 1 kHz steps of hd_pipeline (tracker, expected
 * torque, Kalman filter with the firmware's default = recommended tuning)
 * on the independent double-precision signal of rel_signal.h: a 20 s
 * periodic speed profile with standstill, 300 rad/s and reversals, motor
 * orders 2 and 4, output order 1, 0.02 N m noise.  10^8 steps = 27.8 h.
 *
 * Checks (exit status 1 on any failure, 2 on a bad command line):
 *  - every output finite, every step;
 *  - every K steps (default 1000): state and covariance finite, P exactly
 *    symmetric, P positive semi-definite: smallest eigenvalue (Jacobi, in
 *    double) of P as hd_kf_cov reads it out >= -PSD_ROUNDING x ||P||_F.
 *    The filter holds P in its blocks' co-rotating frames (an orthogonal
 *    change of coordinates: same eigenvalues); hd_kf_cov turns each 2x2 tile
 *    back with two float32 rotations, each entry a sum of at most four
 *    products, so each read-out entry is within 8 u of the sum of the
 *    absolute products (u = 2^-24), and by Weyl's inequality the smallest
 *    eigenvalue moves by at most ||E||_F <= 8 u ||P||_F: PSD_ROUNDING = 8 u;
 *  - no filter reset, and no covariance clamp of either kind (the counters
 *    p_ceiling_count, p_negative_count: the default tuning never reaches
 *    p_max, and a negative variance would be float32 failing);
 *  - error statistics (filtered - truth) of the last window equal those of
 *    the first: windows of min(1 h, (STEPS - 60 s) / 4) whole 20 s periods,
 *    the first starting at 60 s (after convergence).  The two windows see
 *    different misalignment phases (the output angle drifts from period to
 *    period), so their RMS errors agree only to a few per cent: the limit
 *    is 10 % of the RMS; the mean error must stay within 0.01 N m;
 *  - the sharper check: a FRESH pipeline started 60 s before the last
 *    window on the same samples has the same RMS error there within 2 %
 *    (anything the long run accumulated in float32 would show as excess
 *    error in the long-running filter only).
 * Prints key = value lines (and the time per step, a benchmark number).
 */
#define _POSIX_C_SOURCE 199309L /* clock_gettime */
#include <math.h>
#include <stdio.h>
#include <stdlib.h>
#include <string.h>
#include <time.h>

#include "hd_pipeline.h"
#include "rel_signal.h"

#define PERIOD_STEPS 20000ull
#define PSD_ROUNDING (8.0 / 16777216.0) /* 8 u, u = 2^-24 (see above) */
#define WARMUP_STEPS 60000ull
#define HOUR_STEPS 3600000ull
#define RMS_REL_LIMIT 0.10       /* last vs first window */
#define MEAN_DIFF_LIMIT_NM 0.01  /* last vs first window */
#define FRESH_EXCESS_LIMIT 0.02  /* long-running vs fresh filter */

static int usage(void)
{
    fprintf(stderr, "usage: hd_soak [STEPS] [--check-every K] [--seed S]\n"
                    "  STEPS: multiple of 20000, >= 140000 (default 1000000)\n");
    return 2;
}

/* Smallest eigenvalue of the symmetric n x n matrix a (destroyed). */
static double min_eigenvalue(double a[HD_KF_MAX_STATES][HD_KF_MAX_STATES], unsigned n)
{
    for (int sweep = 0; sweep < 60; sweep++) {
        double off = 0.0;
        for (unsigned p = 0; p < n; p++) {
            for (unsigned q = p + 1; q < n; q++) {
                off += a[p][q] * a[p][q];
            }
        }
        if (off < 1e-30) {
            break;
        }
        for (unsigned p = 0; p < n; p++) {
            for (unsigned q = p + 1; q < n; q++) {
                if (fabs(a[p][q]) < 1e-300) {
                    continue;
                }
                double theta = (a[q][q] - a[p][p]) / (2.0 * a[p][q]);
                double t = (theta >= 0.0 ? 1.0 : -1.0) / (fabs(theta) + sqrt(theta * theta + 1.0));
                double c = 1.0 / sqrt(t * t + 1.0);
                double s = t * c;
                for (unsigned k = 0; k < n; k++) {
                    double akp = a[k][p];
                    double akq = a[k][q];
                    a[k][p] = c * akp - s * akq;
                    a[k][q] = s * akp + c * akq;
                }
                for (unsigned k = 0; k < n; k++) {
                    double apk = a[p][k];
                    double aqk = a[q][k];
                    a[p][k] = c * apk - s * aqk;
                    a[q][k] = s * apk + c * aqk;
                }
            }
        }
    }
    double m = a[0][0];
    for (unsigned i = 1; i < n; i++) {
        if (a[i][i] < m) {
            m = a[i][i];
        }
    }
    return m;
}

typedef struct {
    double sum_ms;   /* sum over batches of the batch mean square error */
    double sum_ms2;
    double sum_e;
    unsigned batches;
    double batch_sq;
    uint64_t batch_n;
} window_t;

static void window_add(window_t *w, double e, bool end_of_batch)
{
    w->batch_sq += e * e;
    w->batch_n++;
    w->sum_e += e;
    if (end_of_batch) {
        double ms = w->batch_sq / (double)w->batch_n;
        w->sum_ms += ms;
        w->sum_ms2 += ms * ms;
        w->batches++;
        w->batch_sq = 0.0;
        w->batch_n = 0;
    }
}

static double window_mean(const window_t *w)
{
    return w->sum_ms / (double)w->batches;
}

static double window_var_of_mean(const window_t *w)
{
    double m = window_mean(w);
    double var = (w->sum_ms2 / (double)w->batches - m * m) * (double)w->batches /
                 (double)(w->batches > 1 ? w->batches - 1 : 1);
    return var / (double)w->batches;
}

int main(int argc, char **argv)
{
    uint64_t steps = 1000000ull;
    uint64_t check_every = 1000ull;
    uint64_t seed = 1ull;
    for (int i = 1; i < argc; i++) {
        char *end = NULL;
        if (strcmp(argv[i], "--check-every") == 0 && i + 1 < argc) {
            check_every = strtoull(argv[++i], &end, 10);
        } else if (strcmp(argv[i], "--seed") == 0 && i + 1 < argc) {
            seed = strtoull(argv[++i], &end, 10);
        } else {
            steps = strtoull(argv[i], &end, 10);
        }
        if (end == NULL || *end != '\0') {
            return usage();
        }
    }
    if (steps % PERIOD_STEPS != 0u || steps < WARMUP_STEPS + 4u * PERIOD_STEPS || check_every == 0u) {
        return usage();
    }
    uint64_t win = (steps - WARMUP_STEPS) / 4u;
    if (win > HOUR_STEPS) {
        win = HOUR_STEPS;
    }
    win -= win % PERIOD_STEPS;
    uint64_t first_a = WARMUP_STEPS;
    uint64_t first_b = first_a + win;
    uint64_t last_a = steps - win;

    hd_kf_config_t kcfg;
    /* the firmware default (firmware/hd_fw.h HD_FW_DEFAULT_*) */
    hd_kf_config_recommended(&kcfg, (float)REL_TS_S, 0.02f, 0.05f, 0.02f);
    hd_expected_config_t ecfg;
    hd_expected_config_default(&ecfg);
    static hd_pipeline_t pipe;
    if (hd_pipeline_init(&pipe, &kcfg, &ecfg, HD_TRACK_DEFAULT_BANDWIDTH_HZ) != 0) {
        fprintf(stderr, "hd_soak: pipeline init failed\n");
        return 1;
    }
    rel_signal_t sig;
    rel_signal_init(&sig, seed, 0.02);
    static hd_pipeline_t fresh;
    uint64_t fresh_a = last_a - WARMUP_STEPS;
    double fresh_sq = 0.0, long_sq = 0.0;

    uint64_t non_finite = 0, asym = 0, not_psd = 0, checks = 0;
    uint64_t frozen_steps = 0, clamped_steps = 0, jump_steps = 0;
    double worst_eig_ratio = INFINITY; /* smallest min-eig / ||P||_F seen */
    double max_abs_err = 0.0;
    window_t w_first, w_last;
    memset(&w_first, 0, sizeof w_first);
    memset(&w_last, 0, sizeof w_last);

    struct timespec t0, t1;
    clock_gettime(CLOCK_MONOTONIC, &t0);
    for (uint64_t k = 0; k < steps; k++) {
        rel_signal_step(&sig);
        hd_kf_output_t out;
        hd_pipeline_step(&pipe, (float)sig.meas_nm, sig.d_motor_rad, sig.d_output_rad, 0.0f, 0.0f,
                         &out);
        if (!isfinite(out.torque_filtered_nm) || !isfinite(out.ripple_nm) ||
            !isfinite(out.offset_nm) || !isfinite(out.innovation_var_nm2)) {
            non_finite++;
        }
        frozen_steps += (out.status & HD_KF_STATUS_FROZEN) != 0u;
        clamped_steps += (out.status & HD_KF_STATUS_P_CLAMPED) != 0u;
        jump_steps += (out.status & HD_KF_STATUS_OFFSET_JUMP) != 0u;
        double e = (double)out.torque_filtered_nm - sig.truth_nm;
        bool batch_end = (k + 1u) % PERIOD_STEPS == 0u;
        if (k >= first_a && k < first_b) {
            window_add(&w_first, e, batch_end);
        }
        if (k == fresh_a && hd_pipeline_init(&fresh, &kcfg, &ecfg, HD_TRACK_DEFAULT_BANDWIDTH_HZ) != 0) {
            return 1;
        }
        if (k >= fresh_a) {
            hd_kf_output_t fo;
            hd_pipeline_step(&fresh, (float)sig.meas_nm, sig.d_motor_rad, sig.d_output_rad, 0.0f,
                             0.0f, &fo);
            if (k >= last_a) {
                double ef = (double)fo.torque_filtered_nm - sig.truth_nm;
                fresh_sq += ef * ef;
                long_sq += e * e;
            }
        }
        if (k >= last_a) {
            window_add(&w_last, e, batch_end);
        }
        if (k >= first_a && fabs(e) > max_abs_err) {
            max_abs_err = fabs(e);
        }
        if ((k + 1u) % check_every == 0u) {
            checks++;
            unsigned n = hd_kf_state_count(&pipe.kf);
            static double a[HD_KF_MAX_STATES][HD_KF_MAX_STATES];
            double frob2 = 0.0;
            bool bad = false;
            for (unsigned i = 0; i < n; i++) {
                bad |= !isfinite(hd_kf_state(&pipe.kf, i));
                for (unsigned j = 0; j < n; j++) {
                    float pij = hd_kf_cov(&pipe.kf, i, j);
                    float pji = hd_kf_cov(&pipe.kf, j, i);
                    bad |= !isfinite(pij);
                    if (memcmp(&pij, &pji, sizeof pij) != 0) {
                        asym++;
                    }
                    a[i][j] = (double)pij;
                    frob2 += a[i][j] * a[i][j];
                }
            }
            if (bad) {
                non_finite++;
                continue;
            }
            double frob = sqrt(frob2);
            double ratio = frob > 0.0 ? min_eigenvalue(a, n) / frob : 0.0;
            if (ratio < worst_eig_ratio) {
                worst_eig_ratio = ratio;
            }
            if (ratio < -PSD_ROUNDING) {
                not_psd++;
            }
        }
    }
    clock_gettime(CLOCK_MONOTONIC, &t1);
    double wall_s = (double)(t1.tv_sec - t0.tv_sec) + 1e-9 * (double)(t1.tv_nsec - t0.tv_nsec);

    double ms_f = window_mean(&w_first);
    double ms_l = window_mean(&w_last);
    double z = (ms_l - ms_f) / sqrt(window_var_of_mean(&w_first) + window_var_of_mean(&w_last));
    double rel = fabs(sqrt(ms_l) - sqrt(ms_f)) / sqrt(ms_f);
    double mean_f = w_first.sum_e / (double)win;
    double mean_l = w_last.sum_e / (double)win;
    double rms_fresh = sqrt(fresh_sq / (double)win);
    double rms_long = sqrt(long_sq / (double)win);
    double rel_fresh = (rms_long - rms_fresh) / rms_fresh;
    bool stats_ok = rel < RMS_REL_LIMIT && fabs(mean_l - mean_f) < MEAN_DIFF_LIMIT_NM &&
                    rel_fresh < FRESH_EXCESS_LIMIT;
    bool ok = non_finite == 0u && asym == 0u && not_psd == 0u && pipe.kf.reset_count == 0u &&
              pipe.kf.p_ceiling_count == 0u && pipe.kf.p_negative_count == 0u && stats_ok;

    printf("steps = %llu\n", (unsigned long long)steps);
    printf("hours = %.3f\n", (double)steps * REL_TS_S / 3600.0);
    printf("states = %u\n", hd_kf_state_count(&pipe.kf));
    printf("checks = %llu\n", (unsigned long long)checks);
    printf("non_finite = %llu\n", (unsigned long long)non_finite);
    printf("p_asymmetric_entries = %llu\n", (unsigned long long)asym);
    printf("p_not_psd_checks = %llu\n", (unsigned long long)not_psd);
    printf("p_min_eig_over_frobenius = %.3e\n", worst_eig_ratio);
    printf("p_psd_tolerance_over_frobenius = %.3e\n", PSD_ROUNDING);
    printf("filter_resets = %u\n", (unsigned)pipe.kf.reset_count);
    printf("p_ceiling_clamps = %u\np_negative_clamps = %u\n", (unsigned)pipe.kf.p_ceiling_count,
           (unsigned)pipe.kf.p_negative_count);
    printf("steps_frozen = %llu\nsteps_p_clamped = %llu\nsteps_offset_jump = %llu\n",
           (unsigned long long)frozen_steps, (unsigned long long)clamped_steps,
           (unsigned long long)jump_steps);
    printf("window_s = %.0f\n", (double)win * REL_TS_S);
    printf("rms_err_first_nm = %.5f\nrms_err_last_nm = %.5f\n", sqrt(ms_f), sqrt(ms_l));
    printf("mean_err_first_nm = %.5f\nmean_err_last_nm = %.5f\n", mean_f, mean_l);
    printf("rms_rel_diff_last_vs_first = %.4f\nrms_rel_diff_limit = %g\n", rel, RMS_REL_LIMIT);
    printf("mean_diff_limit_nm = %g\n", MEAN_DIFF_LIMIT_NM);
    printf("mse_batch_z = %.2f\n", z);
    printf("rms_err_last_fresh_filter_nm = %.5f\nrms_excess_long_vs_fresh = %.4f\n", rms_fresh,
           rel_fresh);
    printf("rms_excess_limit = %g\n", FRESH_EXCESS_LIMIT);
    printf("max_abs_err_after_warmup_nm = %.4f\n", max_abs_err);
    printf("wall_s = %.2f\nns_per_step = %.1f\n", wall_s, 1e9 * wall_s / (double)steps);
    printf("result = %s\n", ok ? "PASS" : "FAIL");
    return ok ? 0 : 1;
}
