/*
 * Long-run numerics of the float32 filter: over 10^6 steps (1000 s at 1 kHz)
 * of random speed segments (ramps, reversals, standstill spans where the
 * covariance hits p_max, over-Nyquist spans) the covariance must stay
 * exactly symmetric, positive semi-definite, inside [0, p_max] on the
 * diagonal, and everything finite, with no filter reset.
 *
 * PSD check: a double-precision Cholesky factorisation of P + tol I with
 * tol = 1e-6 max(diag P).  float32 rounding of the covariance update
 * perturbs eigenvalues by ~ n eps max|P| (n <= 17, eps = 6e-8: ~1e-6
 * max|P|); an indefinite P from a wrong update form (e.g. a non-symmetric
 * update or a clamp that is not a congruence) shows up as negative pivots
 * far beyond that.
 */
#include <math.h>
#include <stdio.h>
#include <string.h>

#include "hd_kf.h"
#include "test_util.h"
#include "unity.h"
#include "../reliability/rel_measured.h"

#define TS_S 1e-3
#define GEAR_RATIO 100.0
#define MAX_KNOTS 2000

void setUp(void) {}
void tearDown(void) {}

static double g_t[MAX_KNOTS], g_w[MAX_KNOTS];

/* Random segments of 0.5-6 s: a new speed in [-800, 800] rad/s, or standstill
 * (one segment in four), reached by a linear ramp. */
static size_t make_profile(double duration_s, uint64_t seed)
{
    tu_rng_t r;
    tu_rng_seed(&r, seed);
    size_t n = 0;
    double t = 0.0;
    g_t[n] = 0.0;
    g_w[n++] = 0.0;
    while (t < duration_s && n + 2 < MAX_KNOTS) {
        double w = tu_uniform(&r) < 0.25 ? 0.0 : (tu_uniform(&r) * 2.0 - 1.0) * 800.0;
        t += 0.2 + 1.5 * tu_uniform(&r); /* ramp */
        g_t[n] = t;
        g_w[n++] = w;
        t += 0.5 + 5.0 * tu_uniform(&r); /* hold */
        g_t[n] = t;
        g_w[n++] = w;
    }
    return n;
}

/* Cholesky of (P + shift I) in double; returns the smallest pivot (< 0 if
 * the factorisation fails). */
static double cholesky_min_pivot(double a[HD_KF_MAX_STATES][HD_KF_MAX_STATES], unsigned n,
                                 double shift)
{
    double l[HD_KF_MAX_STATES][HD_KF_MAX_STATES];
    double min_piv = INFINITY;
    for (unsigned j = 0; j < n; j++) {
        double d = a[j][j] + shift;
        for (unsigned k = 0; k < j; k++)
            d -= l[j][k] * l[j][k];
        if (d < min_piv)
            min_piv = d;
        if (!(d > 0.0))
            return d;
        l[j][j] = sqrt(d);
        for (unsigned i = j + 1; i < n; i++) {
            double s = a[i][j];
            for (unsigned k = 0; k < j; k++)
                s -= l[i][k] * l[j][k];
            l[i][j] = s / l[j][j];
        }
    }
    return min_piv;
}

static void long_run(const char *key, const char *name, const hd_kf_config_t *cfg, long steps,
                     uint64_t seed)
{
    static hd_kf_t kf;
    static double p[HD_KF_MAX_STATES][HD_KF_MAX_STATES];
    TEST_ASSERT_EQUAL_INT(HD_KF_OK, hd_kf_init(&kf, cfg));
    size_t knots = make_profile((double)steps * TS_S + 10.0, seed);
    tu_profile_t prof = {g_t, g_w, knots};
    tu_motion_t mo;
    tu_rng_t rng;
    tu_motion_init(&mo, &prof, TS_S);
    tu_rng_seed(&rng, seed ^ 0x5555u);
    unsigned long clamped = 0, frozen = 0, still = 0;
    double worst_rel_pivot = INFINITY, max_diag_seen = 0.0;
    for (long k = 0; k < steps; k++) {
        tu_motion_next(&mo);
        double am = mo.angle_rad, t = (double)mo.k * TS_S;
        double tl = 5.0 + 10.0 * sin(2.0 * TU_PI * 0.1 * t);
        double y = tl + cos(2.0 * am + 0.3) + 0.4 * cos(4.0 * am) +
                   0.5 * cos(am / GEAR_RATIO) + 0.05 * tu_gauss(&rng);
        hd_kf_input_t in = {(float)y, (float)(0.9 * tl), (float)mo.d_angle_rad,
                            (float)(mo.d_angle_rad / GEAR_RATIO), 0.0f};
        hd_kf_output_t o;
        hd_kf_step(&kf, &in, &o);
        clamped += (o.status & HD_KF_STATUS_P_CLAMPED) != 0;
        frozen += o.frozen_mask != 0;
        still += mo.d_angle_rad == 0.0;
        if (!isfinite(o.torque_filtered_nm) || !isfinite(o.ripple_nm) ||
            !isfinite(o.innovation_nm) || !isfinite(o.innovation_var_nm2)) {
            char m[120];
            snprintf(m, sizeof(m), "%s: non-finite output at step %ld", name, k);
            TEST_FAIL_MESSAGE(m);
        }
        unsigned n = hd_kf_state_count(&kf);
        double max_diag = 0.0;
        for (unsigned i = 0; i < n; i++) {
            TEST_ASSERT_FLOAT_IS_DETERMINATE(hd_kf_state(&kf, i));
            for (unsigned j = 0; j < n; j++) {
                float pij = hd_kf_cov(&kf, i, j);
                if (j > i && memcmp(&pij, &(float){hd_kf_cov(&kf, j, i)}, sizeof(float)) != 0) {
                    char m[120];
                    snprintf(m, sizeof(m), "%s: P not exactly symmetric at (%u,%u), step %ld",
                             name, i, j, k);
                    TEST_FAIL_MESSAGE(m);
                }
                TEST_ASSERT_FLOAT_IS_DETERMINATE(pij);
                p[i][j] = (double)pij;
            }
            TEST_ASSERT_GREATER_OR_EQUAL_FLOAT(0.0, p[i][i]);
            TEST_ASSERT_LESS_OR_EQUAL_FLOAT((double)cfg->p_max_nm2 * (1.0 + 1e-6), p[i][i]);
            if (p[i][i] > max_diag)
                max_diag = p[i][i];
        }
        if (max_diag > max_diag_seen)
            max_diag_seen = max_diag;
        double shift = 1e-6 * max_diag;
        double piv = cholesky_min_pivot(p, n, shift);
        if (piv / max_diag < worst_rel_pivot)
            worst_rel_pivot = piv / max_diag;
        if (!(piv > 0.0)) {
            char m[160];
            snprintf(m, sizeof(m), "%s: P not PSD at step %ld (pivot %.3g, max diag %.3g)", name,
                     k, piv, max_diag);
            TEST_FAIL_MESSAGE(m);
        }
    }
    TEST_ASSERT_EQUAL_UINT32(0u, kf.reset_count);
    TEST_ASSERT_EQUAL_UINT32(0u, kf.status_sticky & HD_KF_STATUS_RESET);
    /* every clamped step counted at least one block; rounding never made a
     * block indefinite */
    TEST_ASSERT_TRUE(kf.p_ceiling_count >= clamped);
    TEST_ASSERT_EQUAL_UINT32(0u, kf.p_negative_count);
    char m[300];
    snprintf(m, sizeof(m),
             "%s: %ld steps, %lu standstill, %lu P-clamped (%u blocks counted), %lu with a "
             "frozen block; max diag %.3g; smallest Cholesky pivot / max diag %.3g; symmetric, "
             "PSD, finite",
             name, steps, still, clamped, (unsigned)kf.p_ceiling_count, frozen, max_diag_seen,
             worst_rel_pivot);
    TEST_MESSAGE(m);
    rel_measured(key, "steps=%ld still=%lu clamped=%lu blocks_counted=%u frozen=%lu max_diag=%.3g "
                 "pivot=%.2g", steps, still, clamped, (unsigned)kf.p_ceiling_count, frozen,
                 max_diag_seen, worst_rel_pivot);
    TEST_ASSERT_TRUE(still > 1000);  /* the profile did include standstill */
    TEST_ASSERT_TRUE(frozen > 1000); /* and over-Nyquist spans */
}

static void test_numerics_paper_6th_order_1e6_steps(void)
{
    hd_kf_config_t cfg;
    hd_kf_config_paper(&cfg, (float)TS_S, true);
    long_run("numerics_paper6", "paper 6th order", &cfg, 1000000L, 42u);
}

static void test_numerics_narrowband_offset_5e5_steps(void)
{
    hd_kf_config_t cfg;
    hd_kf_config_default(&cfg, (float)TS_S);
    cfg.r_nm2 = 0.0025f;
    cfg.offset_enabled = 1;
    cfg.offset_q_nm2 = 1e-6f;
    hd_kf_config_add_block(&cfg, HD_KF_LOCK_MOTOR, 2.0f, 1e-5f);
    hd_kf_config_add_block(&cfg, HD_KF_LOCK_MOTOR, 4.0f, 1e-5f);
    hd_kf_config_add_block(&cfg, HD_KF_LOCK_OUTPUT, 1.0f, 1e-5f);
    TEST_ASSERT_EQUAL_INT(HD_KF_OK, hd_kf_config_check(&cfg));
    long_run("numerics_narrow", "narrow-band 6th order + offset", &cfg, 500000L, 7u);
}

static void test_numerics_max_states(void)
{
    hd_kf_config_t cfg;
    hd_kf_config_default(&cfg, (float)TS_S);
    cfg.r_nm2 = 0.01f;
    cfg.offset_enabled = 1;
    cfg.offset_q_nm2 = 1e-6f;
    for (int b = 0; b < HD_KF_MAX_BLOCKS; b++) {
        if (b < HD_KF_MAX_BLOCKS - 2)
            hd_kf_config_add_block(&cfg, HD_KF_LOCK_MOTOR, (float)(b + 1), 1e-3f);
        else if (b == HD_KF_MAX_BLOCKS - 2)
            hd_kf_config_add_block(&cfg, HD_KF_LOCK_OUTPUT, 1.0f, 1e-3f);
        else
            hd_kf_config_add_block(&cfg, HD_KF_LOCK_FIXED, 50.0f, 1e-3f);
    }
    TEST_ASSERT_EQUAL_INT(HD_KF_MAX_BLOCKS, cfg.block_count);
    TEST_ASSERT_EQUAL_INT(HD_KF_OK, hd_kf_config_check(&cfg));
    long_run("numerics_max", "max blocks + offset", &cfg, 200000L, 99u);
}

int main(int argc, char **argv)
{
    if (UnityParseOptions(argc, argv) != 0) {
        return 1;
    }
    UNITY_BEGIN();
    RUN_TEST(test_numerics_paper_6th_order_1e6_steps);
    RUN_TEST(test_numerics_narrowband_offset_5e5_steps);
    RUN_TEST(test_numerics_max_states);
    return UNITY_END();
}
