/*
 * hd_track (angle -> velocity -> acceleration) and hd_expected against
 * closed forms.
 *
 * Tracker: all three observer poles at s = -w (hd_track.h).  For such a
 * type-3 loop driven by the angle (e = theta - theta_hat, theta_hat' = v + l1 e,
 * v' = a + l2 e, a' = l3 e) the velocity state's response to a velocity step
 * is, in continuous time with U = w t,
 *     v_hat / v = 1 + e^-U (U^2 - U - 1)
 * (V_hat/V = (l2 s + l3)/(s+w)^3 = 3w^2/p^2 - 2w^3/p^3, p = s + w, integrated):
 * 24.9 % overshoot at U = 3, within 2 % for U >= 7.9.  The discrete gains
 * approximate these poles to O(w ts); we allow 2 w ts of the step for the
 * discretisation (w ts = 0.031 at 5 Hz, 0.126 at 20 Hz).
 * Constant velocity and constant acceleration are exact fixed points of the
 * documented predict/correct model, so after settling the estimates equal
 * the truth to float32 rounding.
 */
#include <math.h>
#include <stdio.h>

#include "hd_expected.h"
#include "hd_track.h"
#include "unity.h"
#include "../reliability/rel_measured.h"

#define TS_S 1e-3
#define PI_D 3.14159265358979323846

void setUp(void) {}
void tearDown(void) {}

static void test_track_init_validation(void)
{
    hd_track_t t;
    TEST_ASSERT_EQUAL_INT(0, hd_track_init(&t, 1e-3f, HD_TRACK_DEFAULT_BANDWIDTH_HZ));
    TEST_ASSERT_EQUAL_INT(HD_KF_ERR_TRACK_BANDWIDTH, hd_track_init(&t, 0.0f, 20.0f));
    TEST_ASSERT_EQUAL_INT(HD_KF_ERR_TRACK_BANDWIDTH, hd_track_init(&t, -1e-3f, 20.0f));
    TEST_ASSERT_EQUAL_INT(HD_KF_ERR_TRACK_BANDWIDTH, hd_track_init(&t, NAN, 20.0f));
    TEST_ASSERT_EQUAL_INT(HD_KF_ERR_TRACK_BANDWIDTH, hd_track_init(&t, 1e-3f, 0.0f));
    TEST_ASSERT_EQUAL_INT(HD_KF_ERR_TRACK_BANDWIDTH, hd_track_init(&t, 1e-3f, -5.0f));
    TEST_ASSERT_EQUAL_INT(HD_KF_ERR_TRACK_BANDWIDTH, hd_track_init(&t, 1e-3f, NAN));
    TEST_ASSERT_EQUAL_INT(HD_KF_ERR_TRACK_BANDWIDTH, hd_track_init(&t, 1e-3f, INFINITY));
    /* w ts > 0.5 is refused: 100 Hz at 1 kHz is w ts = 0.63; 79 Hz is 0.496 */
    TEST_ASSERT_EQUAL_INT(HD_KF_ERR_TRACK_BANDWIDTH, hd_track_init(&t, 1e-3f, 100.0f));
    TEST_ASSERT_EQUAL_INT(0, hd_track_init(&t, 1e-3f, 79.0f));
    /* gains as documented: l1 = 3 w ts, l2 = 3 w^2 ts, l3 = w^3 ts */
    TEST_ASSERT_EQUAL_INT(0, hd_track_init(&t, 1e-3f, 20.0f));
    double w = 2.0 * PI_D * 20.0;
    TEST_ASSERT_FLOAT_WITHIN(1e-5 * 3 * w * 1e-3, 3 * w * 1e-3, (double)t.l1);
    TEST_ASSERT_FLOAT_WITHIN(1e-5 * 3 * w * w * 1e-3, 3 * w * w * 1e-3, (double)t.l2);
    TEST_ASSERT_FLOAT_WITHIN(1e-5 * w * w * w * 1e-3, w * w * w * 1e-3, (double)t.l3);
}

static void test_track_constant_velocity_exact(void)
{
    hd_track_t t;
    TEST_ASSERT_EQUAL_INT(0, hd_track_init(&t, (float)TS_S, 20.0f));
    const float d = 0.0123f;              /* rad per sample */
    const double v = (double)d / (double)(float)TS_S; /* true speed of the fed increments */
    for (int k = 0; k < 2000; k++)
        TEST_ASSERT_EQUAL_INT(0, hd_track_update(&t, d));
    char m[120];
    snprintf(m, sizeof(m), "constant velocity %.4f rad/s: estimate error %.3g rad/s, acc %.3g",
             v, (double)t.vel_rad_s - v, (double)t.acc_rad_s2);
    TEST_MESSAGE(m);
    const double rel_bound = 1e-5;
    rel_measured("track_constant_velocity", "v=%.1f err=%.2g rel_bound=%g", v,
                 fabs((double)t.vel_rad_s - v), rel_bound);
    TEST_ASSERT_FLOAT_WITHIN(rel_bound * v, v, (double)t.vel_rad_s);
    TEST_ASSERT_FLOAT_WITHIN(1e-2, 0.0, (double)t.acc_rad_s2);
    /* negative direction, same accuracy */
    TEST_ASSERT_EQUAL_INT(0, hd_track_init(&t, (float)TS_S, 20.0f));
    for (int k = 0; k < 2000; k++)
        hd_track_update(&t, -d);
    TEST_ASSERT_FLOAT_WITHIN(rel_bound * v, -v, (double)t.vel_rad_s);
}

/* float32 increments carry ~6e-8 relative rounding each; the loop filters
 * it: 1e-3 rad/s on up to 150 rad/s, 0.05 rad/s^2 */
#define ACC_VEL_BOUND_RAD_S 1e-3
#define ACC_ACC_BOUND_RAD_S2 0.05
static void test_track_constant_acceleration_converges(void)
{
    hd_track_t t;
    TEST_ASSERT_EQUAL_INT(0, hd_track_init(&t, (float)TS_S, 20.0f));
    const double alpha = 50.0;
    double prev = 0.0, worst_v = 0.0, worst_a = 0.0;
    for (int k = 1; k <= 3000; k++) {
        double ang = 0.5 * alpha * (k * TS_S) * (k * TS_S);
        hd_track_update(&t, (float)(ang - prev));
        prev = ang;
        if (k > 1000) { /* 1 s = 125 time constants */
            worst_v = fmax(worst_v, fabs((double)t.vel_rad_s - alpha * k * TS_S));
            worst_a = fmax(worst_a, fabs((double)t.acc_rad_s2 - alpha));
        }
    }
    char m[120];
    snprintf(m, sizeof(m), "constant acceleration 50 rad/s^2: max vel error %.3g rad/s, max acc error %.3g rad/s^2",
             worst_v, worst_a);
    TEST_MESSAGE(m);
    rel_measured("track_constant_acceleration",
                 "vel=%.2g acc=%.2g vel_bound=" BOUND_TEXT(ACC_VEL_BOUND_RAD_S)
                 " acc_bound=" BOUND_TEXT(ACC_ACC_BOUND_RAD_S2), worst_v, worst_a);
    TEST_ASSERT_LESS_OR_EQUAL_FLOAT(ACC_VEL_BOUND_RAD_S, worst_v);
    TEST_ASSERT_LESS_OR_EQUAL_FLOAT(ACC_ACC_BOUND_RAD_S2, worst_a);
}

static double step_closed_form(double u) { return 1.0 + exp(-u) * (u * u - u - 1.0); }

#define STEP_SETTLE_BOUND_U 10 /* 2 % settling, in 1/w: a few time constants */
static void velocity_step(float bw_hz)
{
    hd_track_t t;
    TEST_ASSERT_EQUAL_INT(0, hd_track_init(&t, (float)TS_S, bw_hz));
    const double w = 2.0 * PI_D * (double)bw_hz, v = 10.0;
    double worst_dev = 0.0, settle_u = 0.0, peak = 0.0;
    for (int k = 1; k <= (int)(20.0 / (w * TS_S)); k++) {
        hd_track_update(&t, (float)(v * TS_S));
        double u = w * k * TS_S, y = (double)t.vel_rad_s / v;
        worst_dev = fmax(worst_dev, fabs(y - step_closed_form(u)));
        if (fabs(y - 1.0) > 0.02)
            settle_u = u;
        peak = fmax(peak, y);
    }
    char m[200];
    snprintf(m, sizeof(m), "velocity step, %.0f Hz: max dev from closed form %.3f (w ts %.3f), "
             "overshoot %.1f %% (closed form 24.9 %%), 2 %% settling at %.2f/w (closed form 7.9)",
             (double)bw_hz, worst_dev, w * TS_S, 100.0 * (peak - 1.0), settle_u);
    TEST_MESSAGE(m);
    char key[40];
    snprintf(key, sizeof key, "track_step_%.0f_hz", (double)bw_hz);
    rel_measured(key, "dev=%.3f dev_bound=%.3f overshoot=%.1f settle=%.1f settle_bound="
                 BOUND_TEXT(STEP_SETTLE_BOUND_U),
                 worst_dev, 2.0 * w * TS_S, 100.0 * (peak - 1.0), settle_u);
    TEST_ASSERT_LESS_OR_EQUAL_FLOAT(2.0 * w * TS_S, worst_dev);
    TEST_ASSERT_LESS_OR_EQUAL_FLOAT(STEP_SETTLE_BOUND_U, settle_u);
    TEST_ASSERT_FLOAT_WITHIN(1e-4 * v, v, (double)t.vel_rad_s);
}

static void test_track_velocity_step_matches_closed_form(void)
{
    velocity_step(5.0f);
    velocity_step(20.0f);
}

static void test_track_rejects_nonfinite_increment(void)
{
    hd_track_t t;
    TEST_ASSERT_EQUAL_INT(0, hd_track_init(&t, (float)TS_S, 20.0f));
    for (int k = 0; k < 2000; k++)
        hd_track_update(&t, 0.01f);
    float v0 = t.vel_rad_s;
    TEST_ASSERT_EQUAL_INT(HD_KF_ERR_INPUT, hd_track_update(&t, NAN));
    TEST_ASSERT_EQUAL_INT(HD_KF_ERR_INPUT, hd_track_update(&t, INFINITY));
    TEST_ASSERT_EQUAL_INT(HD_KF_ERR_INPUT, hd_track_update(&t, -INFINITY));
    TEST_ASSERT_FLOAT_IS_DETERMINATE(t.vel_rad_s);
    TEST_ASSERT_FLOAT_IS_DETERMINATE(t.acc_rad_s2);
    TEST_ASSERT_FLOAT_IS_DETERMINATE(t.err_rad);
    /* prediction only: at constant velocity the estimate is unchanged */
    TEST_ASSERT_FLOAT_WITHIN(1e-3, (double)v0, (double)t.vel_rad_s);
    /* and it carries on: after the three lost samples the angle error is 3
     * increments; the loop absorbs it and returns to 10 rad/s */
    for (int k = 0; k < 2000; k++)
        TEST_ASSERT_EQUAL_INT(0, hd_track_update(&t, 0.01f));
    TEST_ASSERT_FLOAT_WITHIN(1e-3, 10.0, (double)t.vel_rad_s);
}

/* ---- expected torque -------------------------------------------------------- */
static double t_exp_ref(double j, double b, double fc, double eps, double v, double a, double ff)
{
    return j * a + b * v + fc * v / (fabs(v) + eps) + ff;
}

static void test_expected_torque_closed_form(void)
{
    hd_expected_config_t c;
    hd_expected_config_default(&c);
    TEST_ASSERT_EQUAL_INT(0, hd_expected_config_check(&c));
    TEST_ASSERT_EQUAL_FLOAT(0.0f, c.inertia_kgm2);
    TEST_ASSERT_EQUAL_FLOAT(0.0f, c.viscous_nm_s_rad);
    TEST_ASSERT_EQUAL_FLOAT(0.0f, c.coulomb_nm);
    TEST_ASSERT_EQUAL_FLOAT(0.01f, c.coulomb_vel_eps_rad_s);
    /* all-zero default: T_exp = T_ff */
    TEST_ASSERT_EQUAL_FLOAT(3.5f, hd_expected_torque_nm(&c, 2.0f, 7.0f, 3.5f));

    c.inertia_kgm2 = 0.8f;
    c.viscous_nm_s_rad = 2.5f;
    c.coulomb_nm = 4.0f;
    c.coulomb_vel_eps_rad_s = 0.05f;
    TEST_ASSERT_EQUAL_INT(0, hd_expected_config_check(&c));
    static const float vel[] = {-3.0f, -0.2f, -0.01f, 0.0f, 1e-4f, 0.05f, 1.0f, 12.0f};
    static const float acc[] = {-40.0f, 0.0f, 3.0f};
    double worst = 0.0;
    for (unsigned i = 0; i < sizeof(vel) / sizeof(vel[0]); i++)
        for (unsigned k = 0; k < sizeof(acc) / sizeof(acc[0]); k++) {
            double want = t_exp_ref(0.8, 2.5, 4.0, 0.05, (double)vel[i], (double)acc[k], -1.25);
            double got = (double)hd_expected_torque_nm(&c, vel[i], acc[k], -1.25f);
            worst = fmax(worst, fabs(got - want));
            TEST_ASSERT_FLOAT_WITHIN(1e-5 * (1.0 + fabs(want)), want, got);
        }
    /* smoothed sign: continuous through zero, odd, -> +-Fc at speed */
    TEST_ASSERT_EQUAL_FLOAT(0.0f, hd_expected_torque_nm(&c, 0.0f, 0.0f, 0.0f));
    float tp = hd_expected_torque_nm(&c, 1e-6f, 0.0f, 0.0f);
    TEST_ASSERT_FLOAT_WITHIN(1e-3, 0.0, (double)tp);
    TEST_ASSERT_FLOAT_WITHIN(1e-6, -(double)tp, (double)hd_expected_torque_nm(&c, -1e-6f, 0.0f, 0.0f));
    c.viscous_nm_s_rad = 0.0f;
    TEST_ASSERT_FLOAT_WITHIN(4.0 * 0.05 / 100.0 + 1e-6, 4.0, (double)hd_expected_torque_nm(&c, 100.0f, 0.0f, 0.0f));
}

static void test_expected_config_check(void)
{
    hd_expected_config_t c;
    hd_expected_config_default(&c); c.inertia_kgm2 = -0.1f;            TEST_ASSERT_EQUAL_INT(HD_KF_ERR_EXPECTED_CONFIG, hd_expected_config_check(&c));
    hd_expected_config_default(&c); c.inertia_kgm2 = NAN;              TEST_ASSERT_EQUAL_INT(HD_KF_ERR_EXPECTED_CONFIG, hd_expected_config_check(&c));
    hd_expected_config_default(&c); c.viscous_nm_s_rad = -1.0f;        TEST_ASSERT_EQUAL_INT(HD_KF_ERR_EXPECTED_CONFIG, hd_expected_config_check(&c));
    hd_expected_config_default(&c); c.viscous_nm_s_rad = INFINITY;     TEST_ASSERT_EQUAL_INT(HD_KF_ERR_EXPECTED_CONFIG, hd_expected_config_check(&c));
    hd_expected_config_default(&c); c.coulomb_nm = -2.0f;              TEST_ASSERT_EQUAL_INT(HD_KF_ERR_EXPECTED_CONFIG, hd_expected_config_check(&c));
    hd_expected_config_default(&c); c.coulomb_vel_eps_rad_s = 0.0f;    TEST_ASSERT_EQUAL_INT(HD_KF_ERR_EXPECTED_CONFIG, hd_expected_config_check(&c));
    hd_expected_config_default(&c); c.coulomb_vel_eps_rad_s = -0.01f;  TEST_ASSERT_EQUAL_INT(HD_KF_ERR_EXPECTED_CONFIG, hd_expected_config_check(&c));
    hd_expected_config_default(&c); c.coulomb_vel_eps_rad_s = NAN;     TEST_ASSERT_EQUAL_INT(HD_KF_ERR_EXPECTED_CONFIG, hd_expected_config_check(&c));
}

int main(int argc, char **argv)
{
    if (UnityParseOptions(argc, argv) != 0) {
        return 1;
    }
    UNITY_BEGIN();
    RUN_TEST(test_track_init_validation);
    RUN_TEST(test_track_constant_velocity_exact);
    RUN_TEST(test_track_constant_acceleration_converges);
    RUN_TEST(test_track_velocity_step_matches_closed_form);
    RUN_TEST(test_track_rejects_nonfinite_increment);
    RUN_TEST(test_expected_torque_closed_form);
    RUN_TEST(test_expected_config_check);
    return UNITY_END();
}
