/* Calibration analysis against closed forms and an independent generator.
 *
 * Experiments are generated here, in double precision with the test's own
 * random numbers, following the paper's procedure: locked wave generator,
 * loading 0 -> +FS, unloading to 0, loading to -FS, unloading to 0. */
#include "hd_calib.h"
#include "unity.h"

#include <math.h>
#include <string.h>

void setUp(void) {}
void tearDown(void) {}

/* ---------------------------------------------------------------- generator */

static uint64_t g_rng = 0x9E3779B97F4A7C15ull;

static double urand(void)
{
    /* xorshift64*: deterministic, independent of the code under test. */
    g_rng ^= g_rng >> 12;
    g_rng ^= g_rng << 25;
    g_rng ^= g_rng >> 27;
    return (double)((g_rng * 2685821657736338717ull) >> 11) * (1.0 / 9007199254740992.0);
}

static double nrand(void)
{
    double u1 = urand(), u2 = urand();
    if (u1 < 1e-300) {
        u1 = 1e-300;
    }
    return sqrt(-2.0 * log(u1)) * cos(6.283185307179586 * u2);
}

typedef struct {
    double gain, offset_v, fs_nm, noise_v;
    double nl_quad_nm;   /* adds nl_quad_nm * (T/FS)^2 to the torque seen */
    double hyst_nm;      /* unloading reads up to hyst_nm further from zero than loading */
    double position_deg;
} gen_t;

static const double k_cycle[21] = {0, .2, .4, .6, .8, 1, .8, .6, .4, .2, 0,
                                   -.2, -.4, -.6, -.8, -1, -.8, -.6, -.4, -.2, 0};
static const int k_unload[21] = {0, 0, 0, 0, 0, 0, 1, 1, 1, 1, 1, 0, 0, 0, 0, 0, 1, 1, 1, 1, 1};

static void gen_experiment(const gen_t *g, hd_calib_experiment_t *e)
{
    memset(e, 0, sizeof *e);
    e->n_points = 21u;
    e->position_deg = (float)g->position_deg;
    for (unsigned i = 0; i < 21u; ++i) {
        double x = k_cycle[i];
        double t = x * g->fs_nm;
        double sgn = x > 0 ? 1.0 : (x < 0 ? -1.0 : 0.0);
        /* Hysteresis loop closing at the turning points: the branches differ
         * by hyst_nm * (1 - x^2). */
        double seen = t + g->nl_quad_nm * x * x +
                      (k_unload[i] ? 0.5 : -0.5) * g->hyst_nm * sgn * (1.0 - x * x);
        e->torque_nm[i] = (float)t;
        e->bridge_v[i] = (float)(g->offset_v + seen / g->gain + g->noise_v * nrand());
        e->direction[i] = k_unload[i] ? HD_CALIB_DIR_UNLOAD : HD_CALIB_DIR_LOAD;
    }
}

static gen_t clean(void)
{
    gen_t g = {6.60, 0.05, 60.0, 0.0, 0.0, 0.0, 0.0};
    return g;
}

static hd_calib_thresholds_t thr(void)
{
    hd_calib_thresholds_t t;
    hd_calib_thresholds_default(&t);
    return t;
}

/* ---------------------------------------------------------------- single fits */

static void test_noise_free_line_is_exact(void)
{
    gen_t g = clean();
    hd_calib_experiment_t e;
    gen_experiment(&g, &e);
    hd_calib_fit_t f;
    TEST_ASSERT_EQUAL_INT(HD_CALIB_OK, hd_calib_fit_experiment(&e, 0.001f, 0.02f, &f));
    TEST_ASSERT_FLOAT_WITHIN(6.6e-5, 6.60, f.gain_nm_per_v);
    TEST_ASSERT_FLOAT_WITHIN(2e-6, 0.05, f.offset_v);
    TEST_ASSERT_FLOAT_WITHIN(1e-6, 60.0, f.full_scale_nm);
    TEST_ASSERT_EQUAL_UINT32(21u, f.n_points);
    TEST_ASSERT_LESS_THAN_FLOAT(0.01f, f.nonlinearity_pct_fs);
    TEST_ASSERT_LESS_THAN_FLOAT(0.01f, f.hysteresis_pct_fs);
    TEST_ASSERT_FALSE(f.nonlinearity_detected);
    TEST_ASSERT_FALSE(f.hysteresis_detected);
}

static void test_known_gain_within_stated_standard_error(void)
{
    /* One noisy experiment: within 3 standard errors. */
    gen_t g = clean();
    g.noise_v = 0.005; /* 5 mV on a +-9 V span */
    hd_calib_experiment_t e;
    gen_experiment(&g, &e);
    hd_calib_fit_t f;
    TEST_ASSERT_EQUAL_INT(HD_CALIB_OK, hd_calib_fit_experiment(&e, 0.001f, 0.02f, &f));
    TEST_ASSERT_TRUE(f.gain_se_nm_per_v > 0.0f);
    TEST_ASSERT_FLOAT_WITHIN(3.0 * (double)f.gain_se_nm_per_v, 6.60, f.gain_nm_per_v);
    TEST_ASSERT_FLOAT_WITHIN(3.0 * (double)f.offset_se_v, 0.05, f.offset_v);
    /* The stated error agrees with the closed form for the known noise:
     * se(slope) = sigma / sqrt(sum (T - mean T)^2), se(gain) = gain^2 se(slope). */
    double st = 0, stt = 0;
    for (unsigned i = 0; i < 21u; ++i) {
        st += (double)e.torque_nm[i];
    }
    for (unsigned i = 0; i < 21u; ++i) {
        double d = (double)e.torque_nm[i] - st / 21.0;
        stt += d * d;
    }
    double se_closed = 6.60 * 6.60 * 0.005 / sqrt(stt);
    /* sigma is estimated from 19 residual dof: its ratio to the truth is
     * within +-40 % with probability > 0.99. */
    TEST_ASSERT_FLOAT_WITHIN(0.4 * se_closed, se_closed, f.gain_se_nm_per_v);
}

static void test_standard_errors_have_nominal_coverage(void)
{
    /* 400 experiments: the truth lies within 1 stated standard error about
     * 68.3 % of the time (binomial sd 2.3 %), for gain and for offset. */
    unsigned in_gain = 0, in_off = 0;
    const unsigned n = 400u;
    for (unsigned k = 0; k < n; ++k) {
        gen_t g = clean();
        g.noise_v = 0.01;
        hd_calib_experiment_t e;
        gen_experiment(&g, &e);
        hd_calib_fit_t f;
        TEST_ASSERT_EQUAL_INT(HD_CALIB_OK, hd_calib_fit_experiment(&e, 0.001f, 0.02f, &f));
        in_gain += fabs((double)f.gain_nm_per_v - 6.60) <= (double)f.gain_se_nm_per_v;
        in_off += fabs((double)f.offset_v - 0.05) <= (double)f.offset_se_v;
    }
    TEST_ASSERT_FLOAT_WITHIN(0.08, 0.683, (double)in_gain / n);
    TEST_ASSERT_FLOAT_WITHIN(0.08, 0.683, (double)in_off / n);
}

static void test_injected_nonlinearity_detected_with_right_size(void)
{
    /* A quadratic q x^2 on symmetric loads is orthogonal to x, so the fitted
     * line is offset by q * mean(x^2) and the largest deviation is
     * q * max(1 - m, m) with m = mean of x^2 over the points. */
    double m = 0;
    for (unsigned i = 0; i < 21u; ++i) {
        m += k_cycle[i] * k_cycle[i];
    }
    m /= 21.0;
    gen_t g = clean();
    g.nl_quad_nm = 0.9; /* N m at full scale */
    g.noise_v = 0.001;
    double expect_pct = 100.0 * g.nl_quad_nm * fmax(1.0 - m, m) / g.fs_nm;
    hd_calib_experiment_t e;
    gen_experiment(&g, &e);
    hd_calib_fit_t f;
    TEST_ASSERT_EQUAL_INT(HD_CALIB_OK, hd_calib_fit_experiment(&e, 0.001f, 0.02f, &f));
    TEST_ASSERT_TRUE(f.nonlinearity_detected);
    TEST_ASSERT_TRUE(f.nonlinearity_p < 1e-6f);
    /* noise: 1 mV * 6.6 N m/V / 60 N m = 0.011 % FS per point. */
    TEST_ASSERT_FLOAT_WITHIN(0.04, expect_pct, f.nonlinearity_pct_fs);
    TEST_ASSERT_FALSE(f.hysteresis_detected);
}

static void test_injected_hysteresis_detected_with_right_size(void)
{
    gen_t g = clean();
    g.hyst_nm = 0.625; /* largest measured branch gap: 0.625 (1 - 0.2^2) = 0.6 N m = 1 % FS */
    g.noise_v = 0.001;
    hd_calib_experiment_t e;
    gen_experiment(&g, &e);
    hd_calib_fit_t f;
    TEST_ASSERT_EQUAL_INT(HD_CALIB_OK, hd_calib_fit_experiment(&e, 0.001f, 0.02f, &f));
    TEST_ASSERT_TRUE(f.hysteresis_detected);
    /* max over 8 levels of |h + noise difference|: noise of a difference is
     * sqrt(2) * 0.011 % FS, so within 0.05 % FS. */
    TEST_ASSERT_FLOAT_WITHIN(0.05, 1.0, f.hysteresis_pct_fs);
    TEST_ASSERT_FALSE(f.nonlinearity_detected);
    /* Nonlinearity uses the midpoint of the branches, so hysteresis does not
     * leak into it (only via the load-only peaks tilting the line a little). */
    TEST_ASSERT_LESS_THAN_FLOAT(0.15f, f.nonlinearity_pct_fs);
}

static void test_clean_noisy_experiments_report_no_effects(void)
{
    unsigned false_nl = 0, false_hy = 0;
    for (unsigned k = 0; k < 200u; ++k) {
        gen_t g = clean();
        g.noise_v = 0.002;
        hd_calib_experiment_t e;
        gen_experiment(&g, &e);
        hd_calib_fit_t f;
        TEST_ASSERT_EQUAL_INT(HD_CALIB_OK, hd_calib_fit_experiment(&e, 0.001f, 0.02f, &f));
        false_nl += f.nonlinearity_detected;
        false_hy += f.hysteresis_detected;
    }
    /* alpha = 0.001: expected 0.2 false detections in 200; allow 2. */
    TEST_ASSERT_LESS_OR_EQUAL(2, false_nl);
    TEST_ASSERT_LESS_OR_EQUAL(2, false_hy);
}

/* ---------------------------------------------------------------- campaign */

/* Eight experiments, four positions (0, 45, 90, 135 deg), each at full and
 * low (20 %) range, as in the paper. */
static void campaign(hd_calib_experiment_t exps[8], const double gains[8], double noise_v,
                     double pos_amp, double pos_phase_deg)
{
    for (unsigned i = 0; i < 8u; ++i) {
        gen_t g = clean();
        g.position_deg = 45.0 * (i % 4u);
        g.fs_nm = (i < 4u) ? 60.0 : 12.0;
        g.noise_v = noise_v;
        double th = 2.0 * g.position_deg * M_PI / 180.0;
        g.gain = gains[i] * (1.0 + pos_amp * cos(th - 2.0 * pos_phase_deg * M_PI / 180.0));
        gen_experiment(&g, &exps[i]);
    }
}

/* Gains 6.60 (1 + 0.02 c_i) with c_i of mean 0 and sample sd exactly 1:
 * std/mean of the gains is exactly 2 %. */
static void spread_gains(double gains[8], double spread)
{
    static const double c[8] = {1, -1, -1, 1, -1, 1, 1, -1}; /* mean 0, sample sd sqrt(8/7) */
    for (unsigned i = 0; i < 8u; ++i) {
        gains[i] = 6.60 * (1.0 + spread * c[i] * sqrt(7.0 / 8.0));
    }
}

static void test_table1_campaign_reports_660_and_2_percent(void)
{
    double gains[8];
    spread_gains(gains, 0.02);
    hd_calib_experiment_t exps[8];
    campaign(exps, gains, 0.0, 0.0, 0.0);
    hd_calib_thresholds_t t = thr();
    static hd_calib_report_t r;
    TEST_ASSERT_EQUAL_INT(HD_CALIB_OK, hd_calib_analyze(exps, 8u, &t, &r));
    TEST_ASSERT_EQUAL_UINT32(8u, r.n_experiments);
    TEST_ASSERT_FLOAT_WITHIN(0.001, 6.60, r.gain_mean_nm_per_v);
    TEST_ASSERT_FLOAT_WITHIN(0.0002, 0.020, r.consistency);
    TEST_ASSERT_TRUE(r.accepted); /* default limit 3 % */
    /* Noisy version: still about 6.60 and 2 %. */
    campaign(exps, gains, 0.002, 0.0, 0.0);
    TEST_ASSERT_EQUAL_INT(HD_CALIB_OK, hd_calib_analyze(exps, 8u, &t, &r));
    TEST_ASSERT_FLOAT_WITHIN(0.02, 6.60, r.gain_mean_nm_per_v);
    TEST_ASSERT_FLOAT_WITHIN(0.002, 0.020, r.consistency);
    TEST_ASSERT_FALSE(r.nonlinearity_detected);
    TEST_ASSERT_FALSE(r.hysteresis_detected);
    TEST_ASSERT_TRUE(r.position_testable);
    /* The alternating spread is not an order-2 pattern in position. */
    TEST_ASSERT_FALSE(r.position_detected);
    /* A tighter limit rejects with the right reason only. */
    t.max_consistency = 0.015f;
    TEST_ASSERT_EQUAL_INT(HD_CALIB_OK, hd_calib_analyze(exps, 8u, &t, &r));
    TEST_ASSERT_FALSE(r.accepted);
    TEST_ASSERT_EQUAL_HEX32(HD_CALIB_REJECT_INCONSISTENT, r.reject_reasons);
}

static void test_position_dependence_detected_with_right_size(void)
{
    double gains[8];
    spread_gains(gains, 0.0);
    hd_calib_experiment_t exps[8];
    campaign(exps, gains, 0.002, 0.03, 30.0); /* 3 % amplitude, peak at 30 deg */
    hd_calib_thresholds_t t = thr();
    static hd_calib_report_t r;
    TEST_ASSERT_EQUAL_INT(HD_CALIB_OK, hd_calib_analyze(exps, 8u, &t, &r));
    TEST_ASSERT_TRUE(r.position_testable);
    TEST_ASSERT_TRUE(r.position_detected);
    TEST_ASSERT_FLOAT_WITHIN(0.1, 3.0, r.position_amplitude_pct);
    TEST_ASSERT_FLOAT_WITHIN(2.0, 30.0, r.position_phase_deg);
    TEST_ASSERT_FALSE(r.accepted);
    TEST_ASSERT_TRUE(r.reject_reasons & HD_CALIB_REJECT_POSITION);
    /* Clean campaign: nothing. */
    campaign(exps, gains, 0.002, 0.0, 0.0);
    TEST_ASSERT_EQUAL_INT(HD_CALIB_OK, hd_calib_analyze(exps, 8u, &t, &r));
    TEST_ASSERT_FALSE(r.position_detected);
    TEST_ASSERT_LESS_THAN_FLOAT(0.1f, r.position_amplitude_pct);
    TEST_ASSERT_TRUE(r.accepted);
    TEST_ASSERT_EQUAL_HEX32(0u, r.reject_reasons);
}

static void test_position_not_testable_with_two_positions(void)
{
    double gains[8];
    spread_gains(gains, 0.01);
    hd_calib_experiment_t exps[8];
    campaign(exps, gains, 0.001, 0.0, 0.0);
    for (unsigned i = 0; i < 8u; ++i) {
        exps[i].position_deg = (i & 1u) ? 90.0f : 0.0f;
    }
    hd_calib_thresholds_t t = thr();
    static hd_calib_report_t r;
    TEST_ASSERT_EQUAL_INT(HD_CALIB_OK, hd_calib_analyze(exps, 8u, &t, &r));
    TEST_ASSERT_FALSE(r.position_testable);
    TEST_ASSERT_TRUE(isnan(r.position_p));
    /* a limit that cannot be checked is not met, unless allowed */
    TEST_ASSERT_FALSE(r.accepted);
    TEST_ASSERT_EQUAL_HEX32(HD_CALIB_REJECT_NOT_MEASURABLE, r.reject_reasons);
    t.allow_unmeasurable = 1u;
    TEST_ASSERT_EQUAL_INT(HD_CALIB_OK, hd_calib_analyze(exps, 8u, &t, &r));
    TEST_ASSERT_TRUE(r.accepted);
}

/* Two points per experiment (0 and full scale, loading only): the gain is
 * there, but no nonlinearity (a line fits two levels exactly), no
 * hysteresis (one direction) and no standard error. */
static void test_two_point_experiments_are_not_measurable(void)
{
    double gains[8];
    spread_gains(gains, 0.01);
    hd_calib_experiment_t exps[8];
    campaign(exps, gains, 0.001, 0.0, 0.0);
    for (unsigned i = 0; i < 8u; ++i) {
        /* keep points 0 (0 N m, load) and 5 (+FS, load) */
        exps[i].torque_nm[1] = exps[i].torque_nm[5];
        exps[i].bridge_v[1] = exps[i].bridge_v[5];
        exps[i].direction[1] = HD_CALIB_DIR_LOAD;
        exps[i].n_points = 2u;
    }
    hd_calib_thresholds_t t = thr();
    static hd_calib_report_t r;
    TEST_ASSERT_EQUAL_INT(HD_CALIB_OK, hd_calib_analyze(exps, 8u, &t, &r));
    for (unsigned i = 0; i < 8u; ++i) {
        TEST_ASSERT_FALSE(r.fit[i].nonlinearity_measurable);
        TEST_ASSERT_FALSE(r.fit[i].hysteresis_measurable);
        TEST_ASSERT_TRUE(isnan(r.fit[i].nonlinearity_pct_fs));
        TEST_ASSERT_TRUE(isnan(r.fit[i].hysteresis_pct_fs));
        TEST_ASSERT_TRUE(isnan(r.fit[i].gain_se_nm_per_v));
        TEST_ASSERT_FLOAT_WITHIN(0.01f * 6.6f * 4.0f, 6.60f, r.fit[i].gain_nm_per_v);
    }
    TEST_ASSERT_TRUE(isnan(r.nonlinearity_pct_fs));
    TEST_ASSERT_TRUE(isnan(r.hysteresis_pct_fs));
    TEST_ASSERT_FALSE(r.accepted);
    TEST_ASSERT_EQUAL_HEX32(HD_CALIB_REJECT_NOT_MEASURABLE, r.reject_reasons);
}

/* Loading only, both torque directions (0 -> FS, 0 -> -FS): nonlinearity
 * measurable, hysteresis not; the worst hysteresis is over the measurable
 * experiments only. */
static void test_one_direction_has_no_hysteresis(void)
{
    double gains[8];
    spread_gains(gains, 0.0);
    hd_calib_experiment_t exps[8];
    campaign(exps, gains, 0.001, 0.0, 0.0);
    hd_calib_experiment_t *e = &exps[2];
    uint32_t n = 0;
    for (uint32_t i = 0; i < e->n_points; ++i) {
        if (e->direction[i] == HD_CALIB_DIR_LOAD) {
            e->torque_nm[n] = e->torque_nm[i];
            e->bridge_v[n] = e->bridge_v[i];
            e->direction[n++] = HD_CALIB_DIR_LOAD;
        }
    }
    e->n_points = n; /* 11 points: 0, +-0.2 .. +-1 FS */
    hd_calib_thresholds_t t = thr();
    static hd_calib_report_t r;
    TEST_ASSERT_EQUAL_INT(HD_CALIB_OK, hd_calib_analyze(exps, 8u, &t, &r));
    TEST_ASSERT_TRUE(r.fit[2].nonlinearity_measurable);
    TEST_ASSERT_FALSE(r.fit[2].hysteresis_measurable);
    TEST_ASSERT_TRUE(isnan(r.fit[2].hysteresis_pct_fs));
    TEST_ASSERT_TRUE(r.fit[1].hysteresis_measurable);
    TEST_ASSERT_FALSE(r.hysteresis_measurable);
    TEST_ASSERT_TRUE(r.nonlinearity_measurable);
    TEST_ASSERT_TRUE(isfinite(r.hysteresis_pct_fs)); /* from the other seven */
    TEST_ASSERT_FALSE(r.accepted);
    TEST_ASSERT_EQUAL_HEX32(HD_CALIB_REJECT_NOT_MEASURABLE, r.reject_reasons);
}

static void test_nonlinearity_rejects_above_limit(void)
{
    double gains[8];
    spread_gains(gains, 0.0);
    hd_calib_experiment_t exps[8];
    campaign(exps, gains, 0.001, 0.0, 0.0);
    gen_t g = clean();
    g.nl_quad_nm = 2.0; /* 2 N m at 60 N m: about 1.9 % FS deviation */
    g.noise_v = 0.001;
    gen_experiment(&g, &exps[0]);
    hd_calib_thresholds_t t = thr();
    static hd_calib_report_t r;
    TEST_ASSERT_EQUAL_INT(HD_CALIB_OK, hd_calib_analyze(exps, 8u, &t, &r));
    TEST_ASSERT_TRUE(r.nonlinearity_detected);
    TEST_ASSERT_TRUE(r.fit[0].nonlinearity_detected);
    TEST_ASSERT_FALSE(r.fit[1].nonlinearity_detected);
    TEST_ASSERT_FALSE(r.accepted);
    TEST_ASSERT_TRUE(r.reject_reasons & HD_CALIB_REJECT_NONLINEAR);
}

/* ---------------------------------------------------------------- bad input */

static void test_bad_input_errors(void)
{
    hd_calib_experiment_t e[2];
    gen_t g = clean();
    gen_experiment(&g, &e[0]);
    gen_experiment(&g, &e[1]);
    hd_calib_thresholds_t t = thr();
    static hd_calib_report_t r;
    hd_calib_fit_t f;

    e[1].n_points = 1u;
    TEST_ASSERT_EQUAL_INT(HD_CALIB_ERR_TOO_FEW_POINTS, hd_calib_analyze(e, 2u, &t, &r));
    TEST_ASSERT_EQUAL_INT(1, r.error_experiment);
    e[1].n_points = 0u;
    TEST_ASSERT_EQUAL_INT(HD_CALIB_ERR_TOO_FEW_POINTS, hd_calib_fit_experiment(&e[1], 0.001f, 0.02f, &f));
    e[1].n_points = HD_CALIB_MAX_POINTS + 1u;
    TEST_ASSERT_EQUAL_INT(HD_CALIB_ERR_ARG, hd_calib_fit_experiment(&e[1], 0.001f, 0.02f, &f));
    gen_experiment(&g, &e[1]);

    for (unsigned i = 0; i < 21u; ++i) {
        e[1].torque_nm[i] = 10.0f;
    }
    TEST_ASSERT_EQUAL_INT(HD_CALIB_ERR_LOADS_EQUAL, hd_calib_analyze(e, 2u, &t, &r));
    gen_experiment(&g, &e[1]);

    e[1].bridge_v[3] = NAN;
    TEST_ASSERT_EQUAL_INT(HD_CALIB_ERR_NONFINITE, hd_calib_analyze(e, 2u, &t, &r));
    e[1].bridge_v[3] = 1.0f;
    e[1].torque_nm[4] = INFINITY;
    TEST_ASSERT_EQUAL_INT(HD_CALIB_ERR_NONFINITE, hd_calib_analyze(e, 2u, &t, &r));
    gen_experiment(&g, &e[1]);
    e[1].position_deg = NAN;
    TEST_ASSERT_EQUAL_INT(HD_CALIB_ERR_NONFINITE, hd_calib_analyze(e, 2u, &t, &r));
    gen_experiment(&g, &e[1]);

    e[1].direction[2] = 7u;
    TEST_ASSERT_EQUAL_INT(HD_CALIB_ERR_DIRECTION, hd_calib_analyze(e, 2u, &t, &r));
    gen_experiment(&g, &e[1]);

    for (unsigned i = 0; i < 21u; ++i) {
        e[1].bridge_v[i] = -e[1].bridge_v[i]; /* reversed wiring */
    }
    TEST_ASSERT_EQUAL_INT(HD_CALIB_ERR_SLOPE, hd_calib_analyze(e, 2u, &t, &r));
    gen_experiment(&g, &e[1]);

    /* A single experiment: fitted, but no consistency measure, never accepted. */
    TEST_ASSERT_EQUAL_INT(HD_CALIB_ERR_SINGLE_EXPERIMENT, hd_calib_analyze(e, 1u, &t, &r));
    TEST_ASSERT_TRUE(isnan(r.consistency));
    TEST_ASSERT_FLOAT_WITHIN(1e-3, 6.60, r.fit[0].gain_nm_per_v);
    TEST_ASSERT_FALSE(r.accepted);
    TEST_ASSERT_TRUE(r.reject_reasons & HD_CALIB_REJECT_FEW_EXPERIMENTS);

    TEST_ASSERT_EQUAL_INT(HD_CALIB_ERR_ARG, hd_calib_analyze(e, 0u, &t, &r));
    TEST_ASSERT_EQUAL_INT(HD_CALIB_ERR_ARG, hd_calib_analyze(NULL, 2u, &t, &r));
    TEST_ASSERT_EQUAL_INT(HD_CALIB_ERR_ARG, hd_calib_analyze(e, HD_CALIB_MAX_EXPERIMENTS + 1u, &t, &r));
    TEST_ASSERT_EQUAL_INT(HD_CALIB_ERR_ARG, hd_calib_analyze(e, 2u, &t, NULL));
    t.alpha = 0.0f;
    TEST_ASSERT_EQUAL_INT(HD_CALIB_ERR_ARG, hd_calib_analyze(e, 2u, &t, &r));
    TEST_ASSERT_EQUAL_INT(HD_CALIB_ERR_ARG, hd_calib_fit_experiment(NULL, 0.001f, 0.02f, &f));

    /* Every code has its own message. */
    for (int c = -7; c <= 0; ++c) {
        TEST_ASSERT_TRUE(strcmp(hd_calib_strerror(c), "unknown error") != 0);
    }
    TEST_ASSERT_EQUAL_STRING("unknown error", hd_calib_strerror(-99));
}

static void test_f_pvalue_against_published_tables(void)
{
    /* Critical values from standard F tables. */
    TEST_ASSERT_FLOAT_WITHIN(2e-4, 0.05, hd_calib_f_pvalue(4.964603f, 1.0f, 10.0f));
    TEST_ASSERT_FLOAT_WITHIN(5e-5, 0.01, hd_calib_f_pvalue(13.27393f, 2.0f, 5.0f));
    TEST_ASSERT_FLOAT_WITHIN(2e-4, 0.05, hd_calib_f_pvalue(3.098391f, 3.0f, 20.0f));
    TEST_ASSERT_FLOAT_WITHIN(2e-4, 0.05, hd_calib_f_pvalue(161.4476f, 1.0f, 1.0f));
    /* F(2, df) has the closed form p = (1 + 2F/df)^(-df/2). */
    TEST_ASSERT_FLOAT_WITHIN(1e-5, pow(1.0 + 2.0 * 3.0 / 16.0, -8.0), hd_calib_f_pvalue(3.0f, 2.0f, 16.0f));
    TEST_ASSERT_EQUAL_FLOAT(1.0f, hd_calib_f_pvalue(0.0f, 2.0f, 5.0f));
    TEST_ASSERT_EQUAL_FLOAT(0.0f, hd_calib_f_pvalue(INFINITY, 2.0f, 5.0f));
    TEST_ASSERT_TRUE(isnan(hd_calib_f_pvalue(1.0f, 0.0f, 5.0f)));
}

int main(int argc, char **argv)
{
    if (UnityParseOptions(argc, argv) != 0) {
        return 1;
    }
    UNITY_BEGIN();
    RUN_TEST(test_noise_free_line_is_exact);
    RUN_TEST(test_known_gain_within_stated_standard_error);
    RUN_TEST(test_standard_errors_have_nominal_coverage);
    RUN_TEST(test_injected_nonlinearity_detected_with_right_size);
    RUN_TEST(test_injected_hysteresis_detected_with_right_size);
    RUN_TEST(test_clean_noisy_experiments_report_no_effects);
    RUN_TEST(test_table1_campaign_reports_660_and_2_percent);
    RUN_TEST(test_position_dependence_detected_with_right_size);
    RUN_TEST(test_position_not_testable_with_two_positions);
    RUN_TEST(test_two_point_experiments_are_not_measurable);
    RUN_TEST(test_one_direction_has_no_hysteresis);
    RUN_TEST(test_nonlinearity_rejects_above_limit);
    RUN_TEST(test_bad_input_errors);
    RUN_TEST(test_f_pvalue_against_published_tables);
    return UNITY_END();
}
