/* hd_expected's motor-current term against its closed form, evaluated here
 * in double:
 *   T_cur = k_i i - J_r acc - b_r vel - Fc_r vel / (|vel| + v_eps)
 * scaled by k_b / k_i where the load drives the motor (T_cur vel < 0,
 * blended in like the Coulomb sign; k_i at standstill), and its
 * configuration check.  (A filter-library unit test kept with the
 * firmware tests: the firmware is its only caller; docs/design/slow-torque.md.) */
#include <math.h>

#include "hd_expected.h"
#include "unity.h"

void setUp(void) {}
void tearDown(void) {}

static double closed_form(double ki, double fc, double b, double j, double eps, double i,
                          double v, double a)
{
    return ki * i - j * a - b * v - fc * v / (fabs(v) + eps);
}

static void test_current_term_matches_the_closed_form(void)
{
    hd_expected_config_t e;
    hd_expected_config_default(&e);
    e.coulomb_vel_eps_rad_s = 0.02f;
    e.coulomb_nm = 123.0f; /* the load model's own terms do not enter T_cur */
    const hd_expected_current_config_t c = {161.5f, 1.7f, 0.9f, 2.4f, 0.0f, 0.0f}; /* one efficiency */
    const float cur[] = {-12.0f, -0.3f, 0.0f, 0.05f, 7.5f};
    const float vel[] = {-3.0f, -0.01f, 0.0f, 1e-4f, 0.5f, 2.9f};
    const float acc[] = {-40.0f, 0.0f, 12.5f};
    unsigned n = 0;
    for (unsigned a = 0; a < 5; a++) {
        for (unsigned b = 0; b < 6; b++) {
            for (unsigned d = 0; d < 3; d++) {
                double expect = closed_form(161.5, 1.7, 0.9, 2.4, 0.02, (double)cur[a],
                                            (double)vel[b], (double)acc[d]);
                double got = (double)hd_expected_current_nm(&c, &e, cur[a], vel[b], acc[d]);
                TEST_ASSERT_DOUBLE_WITHIN(1e-6 * (1.0 + fabs(expect)), expect, got);
                n++;
            }
        }
    }
    TEST_ASSERT_EQUAL_UINT(90, n);
    /* odd in the current, friction opposes the motion */
    TEST_ASSERT_EQUAL_FLOAT(-hd_expected_current_nm(&c, &e, 2.0f, 0.0f, 0.0f),
                            hd_expected_current_nm(&c, &e, -2.0f, 0.0f, 0.0f));
    TEST_ASSERT_TRUE(hd_expected_current_nm(&c, &e, 0.0f, 1.0f, 0.0f) < 0.0f);
    /* all zero: no term */
    const hd_expected_current_config_t off = {0.0f, 0.0f, 0.0f, 0.0f, 0.0f, 0.0f};
    TEST_ASSERT_EQUAL_FLOAT(0.0f, hd_expected_current_nm(&off, &e, 30.0f, 2.0f, 100.0f));
}

/* Two efficiencies (eta 0.90 driving, eta_b 0.85 driven, as the simulated
 * drive): k_b / k_i = 1 / (eta eta_b).  Far from standstill the term is
 * T_cur where it goes with the motion and (k_b / k_i) T_cur where it
 * opposes it; at standstill T_cur; in between, the closed form's blend. */
static void test_backdrive_gain_where_the_load_drives_the_motor(void)
{
    hd_expected_config_t e;
    hd_expected_config_default(&e);
    e.coulomb_vel_eps_rad_s = 0.02f;
    const double ki = 100.0 * 0.9 * 0.1, kb = 100.0 * 0.1 / 0.85;
    const hd_expected_current_config_t c = {(float)ki, 1.7f, 0.9f, 2.4f, (float)kb, 0.0f};
    const float cur[] = {-12.0f, -0.3f, 0.0f, 0.05f, 7.5f};
    const float vel[] = {-3.0f, -0.01f, 0.0f, 1e-4f, 0.5f, 2.9f};
    const float acc[] = {-40.0f, 0.0f, 12.5f};
    for (unsigned a = 0; a < 5; a++) {
        for (unsigned b = 0; b < 6; b++) {
            for (unsigned d = 0; d < 3; d++) {
                const double v = (double)vel[b];
                const double u = closed_form(ki, 1.7, 0.9, 2.4, 0.02, (double)cur[a], v,
                                             (double)acc[d]);
                const double along = (u >= 0.0 ? 1.0 : -1.0) * v / (fabs(v) + 0.02);
                const double back = along < 0.0 ? -along : 0.0;
                const double expect = u * (1.0 + back * (kb / ki - 1.0));
                double got = (double)hd_expected_current_nm(&c, &e, cur[a], vel[b], acc[d]);
                TEST_ASSERT_DOUBLE_WITHIN(1e-5 * (1.0 + fabs(expect)), expect, got);
            }
        }
    }
    /* lifting (torque with the motion) and lowering (against it), fast:
     * the same current means 1 / (eta eta_b) = 1.307 times the torque */
    const hd_expected_current_config_t bare = {(float)ki, 0.0f, 0.0f, 0.0f, (float)kb, 0.0f};
    const float lift = hd_expected_current_nm(&bare, &e, 5.0f, 2.0f, 0.0f);
    const float lower = hd_expected_current_nm(&bare, &e, 5.0f, -2.0f, 0.0f);
    TEST_ASSERT_FLOAT_WITHIN(0.01f * 5.0f * (float)ki, 5.0f * (float)ki, lift);
    TEST_ASSERT_FLOAT_WITHIN(0.02f, (float)(1.0 / (0.9 * 0.85)), lower / lift);
    /* holding at standstill: the driving gain */
    TEST_ASSERT_FLOAT_WITHIN(1e-4f, 5.0f * (float)ki, hd_expected_current_nm(&bare, &e, 5.0f,
                                                                           0.0f, 0.0f));
}

static void test_current_config_check(void)
{
    hd_expected_current_config_t c = {10.0f, 0.1f, 0.2f, 0.3f, 12.0f, 0.05f};
    TEST_ASSERT_EQUAL_INT(HD_KF_OK, hd_expected_current_check(&c));
    TEST_ASSERT_EQUAL_INT(HD_KF_ERR_NULL, hd_expected_current_check(NULL));
    float *f[6] = {&c.nm_per_a,     &c.coulomb_nm,         &c.viscous_nm_s_rad,
                   &c.inertia_kgm2, &c.backdrive_nm_per_a, &c.error_nm};
    const float bad[3] = {-1.0f, NAN, INFINITY};
    for (unsigned i = 0; i < 6; i++) {
        for (unsigned k = 0; k < 3; k++) {
            const float keep = *f[i];
            *f[i] = bad[k];
            TEST_ASSERT_EQUAL_INT(HD_KF_ERR_EXPECTED_CONFIG, hd_expected_current_check(&c));
            *f[i] = keep;
        }
    }
}

/* k_i = N kt eta, k_b = N kt / eta_b: k_i / k_b = eta eta_b.  A model with
 * k_b below k_i says eta eta_b > 1 (a gear that makes energy), one with
 * k_b above 100 k_i says below 1 % (no gear): both refused; k_b = k_i (one
 * efficiency of 1) and either gain alone are accepted. */
static void test_current_efficiencies_must_be_physical(void)
{
    hd_expected_current_config_t c = {10.0f, 0.1f, 0.2f, 0.3f, 9.9f, 0.0f};
    TEST_ASSERT_EQUAL_INT(HD_KF_ERR_EXPECTED_CONFIG, hd_expected_current_check(&c));
    c.backdrive_nm_per_a = 10.0f;
    TEST_ASSERT_EQUAL_INT(HD_KF_OK, hd_expected_current_check(&c));
    c.backdrive_nm_per_a = 10.0f / HD_EXPECTED_MIN_EFFICIENCY_PRODUCT;
    TEST_ASSERT_EQUAL_INT(HD_KF_OK, hd_expected_current_check(&c));
    c.backdrive_nm_per_a = 1.01f * 10.0f / HD_EXPECTED_MIN_EFFICIENCY_PRODUCT;
    TEST_ASSERT_EQUAL_INT(HD_KF_ERR_EXPECTED_CONFIG, hd_expected_current_check(&c));
    c.backdrive_nm_per_a = 0.0f; /* one efficiency */
    TEST_ASSERT_EQUAL_INT(HD_KF_OK, hd_expected_current_check(&c));
    c.nm_per_a = 0.0f;
    c.backdrive_nm_per_a = 3.0f; /* current unused: nothing to compare */
    TEST_ASSERT_EQUAL_INT(HD_KF_OK, hd_expected_current_check(&c));
}

int main(int argc, char **argv)
{
    if (UnityParseOptions(argc, argv) != 0) {
        return 1;
    }
    UNITY_BEGIN();
    RUN_TEST(test_current_term_matches_the_closed_form);
    RUN_TEST(test_backdrive_gain_where_the_load_drives_the_motor);
    RUN_TEST(test_current_config_check);
    RUN_TEST(test_current_efficiencies_must_be_physical);
    return UNITY_END();
}
