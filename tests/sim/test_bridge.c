/* Rosette bridge (sim/hd_bridge.h) against equations 1-4 of the paper
 * and the first-order placement-error prediction derived in hd_bridge.h. */
#include <math.h>

#include "hd_bridge.h"
#include "unity.h"

#define PI_D 3.14159265358979323846

void setUp(void) {}
void tearDown(void) {}

/* Least-squares fit of a*sin(2b) + c*cos(2b) + d over one full period of
 * uniformly spaced samples (orthogonal basis: plain projections). */
static void fit_2x(const hd_bridge_config_t *cfg, float torque_nm,
                   double *a_sin, double *c_cos, double *mean)
{
    const int n = 720;
    double s = 0.0, c = 0.0, m = 0.0;
    for (int i = 0; i < n; i++) {
        const double beta = 2.0 * PI_D * i / n;
        const double v = (double)hd_bridge_output_v(cfg, torque_nm, (float)beta);
        s += v * sin(2.0 * beta);
        c += v * cos(2.0 * beta);
        m += v;
    }
    *a_sin = 2.0 * s / n;
    *c_cos = 2.0 * c / n;
    *mean = m / n;
}

static void test_default_gain_is_table_one(void)
{
    hd_bridge_config_t cfg;
    hd_bridge_config_default(&cfg);
    TEST_ASSERT_FLOAT_WITHIN(1e-4, 6.60, hd_bridge_gain_nm_per_v(&cfg));
    /* 6.6 N m must give 1.0 V at the amplifier (ideal placement). */
    TEST_ASSERT_FLOAT_WITHIN(1e-5, 1.0, hd_bridge_output_v(&cfg, 6.6f, 0.3f));
}

static void test_equation4_output_is_k_eps_e(void)
{
    hd_bridge_config_t cfg;
    hd_bridge_config_default(&cfg);
    cfg.gauge_factor = 2.1f;
    cfg.supply_v = 5.0f;
    cfg.amp_gain = 500.0f;
    cfg.strain_per_nm = 1e-5f;
    const double expect = 2.1 * 1e-5 * 12.5 * 5.0 * 500.0; /* K eps_t E G */
    TEST_ASSERT_FLOAT_WITHIN(1e-6 * expect, expect, hd_bridge_output_v(&cfg, 12.5f, 1.0f));
}

static void test_ideal_placement_cancels_modulation(void)
{
    hd_bridge_config_t cfg;
    hd_bridge_config_default(&cfg);
    cfg.psi0 = 1e-3f; /* huge modulation: 26x the torsional strain of 1 N m */
    const double v_nm = 1.0 / 6.60;
    for (int i = 0; i < 200; i++) {
        const float beta = 0.0314159f * (float)i;
        const double v = (double)hd_bridge_output_v(&cfg, 1.0f, beta);
        TEST_ASSERT_DOUBLE_WITHIN(1e-6, v_nm, v);
    }
}

static void test_placement_error_leaves_first_order_2x_line(void)
{
    hd_bridge_config_t cfg;
    hd_bridge_config_default(&cfg);
    cfg.psi0 = 4e-5f;
    cfg.placement_error_rad[0] = 2e-3f;
    cfg.placement_error_rad[1] = -1e-3f;
    cfg.placement_error_rad[2] = 0.5e-3f;
    cfg.placement_error_rad[3] = 1.5e-3f;
    /* S = 2 + 1 + 0.5 - 1.5 = 2 mrad; line = -(K E G psi0 / 4) S cos 2b. */
    const double s = 2e-3;
    const double kegp = 2.0 * 10.0 * 1000.0 * 4e-5;
    const double expect_cos = -kegp * s / 4.0;
    double a, c, m;
    fit_2x(&cfg, 3.0f, &a, &c, &m);
    TEST_ASSERT_DOUBLE_WITHIN(0.01 * fabs(expect_cos), expect_cos, c);
    /* the sine part is second order in delta: |.| <= K E G psi0 sum(delta^2)/4 */
    TEST_ASSERT_LESS_THAN_FLOAT(kegp * 8e-6 / 4.0 + 1e-7, fabs(a));
    TEST_ASSERT_DOUBLE_WITHIN(1e-5, 3.0 / 6.60, m);
    TEST_ASSERT_FLOAT_WITHIN(1e-9, fabs(expect_cos), hd_bridge_residual_2x_v(&cfg));
}

static void test_common_shift_of_all_rosettes_cancels(void)
{
    /* Rotating the whole pattern by delta changes no difference: S = 0. */
    hd_bridge_config_t cfg;
    hd_bridge_config_default(&cfg);
    cfg.psi0 = 1e-3f;
    for (int k = 0; k < 4; k++) {
        cfg.placement_error_rad[k] = 0.05f;
    }
    double a, c, m;
    fit_2x(&cfg, 0.0f, &a, &c, &m);
    TEST_ASSERT_DOUBLE_WITHIN(1e-6, 0.0, a);
    TEST_ASSERT_DOUBLE_WITHIN(1e-6, 0.0, c);
}

static void test_bad_input_gives_nan(void)
{
    hd_bridge_config_t cfg;
    hd_bridge_config_default(&cfg);
    TEST_ASSERT_TRUE(isnan(hd_bridge_output_v(NULL, 1.0f, 0.0f)));
    TEST_ASSERT_TRUE(isnan(hd_bridge_output_v(&cfg, NAN, 0.0f)));
    TEST_ASSERT_TRUE(isnan(hd_bridge_output_v(&cfg, 1.0f, INFINITY)));
    cfg.amp_gain = 0.0f;
    TEST_ASSERT_TRUE(isnan(hd_bridge_gain_nm_per_v(&cfg)));
}

int main(int argc, char **argv)
{
    if (UnityParseOptions(argc, argv) != 0) {
        return 1;
    }
    UNITY_BEGIN();
    RUN_TEST(test_default_gain_is_table_one);
    RUN_TEST(test_equation4_output_is_k_eps_e);
    RUN_TEST(test_ideal_placement_cancels_modulation);
    RUN_TEST(test_placement_error_leaves_first_order_2x_line);
    RUN_TEST(test_common_shift_of_all_rosettes_cancels);
    RUN_TEST(test_bad_input_gives_nan);
    return UNITY_END();
}
