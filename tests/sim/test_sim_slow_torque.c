/* The simulated joint's slow-torque parts (issue 12, docs/reference/sim.md): arm
 * gravity with a payload change, slow sinusoidal loads, the controller's
 * feed-forward (its own parameters, dropouts, frame period) and the motor
 * current (efficiency by direction of power flow, kt error, noise), against
 * closed forms written here from the documented model. */
#include <math.h>
#include <stdio.h>
#include <string.h>

#include "hal_sim.h"
#include "hd_sim_plant.h"
#include "hd_sim_scenario.h"
#include "sim_run.h"
#include "unity.h"

#define MAXN 6000
#define PI_D 3.14159265358979323846

static hd_sim_plant_t plant;
static hd_sim_sample_t run[MAXN];
static double acc_m[MAXN];
static char err[512];

void setUp(void) {}
void tearDown(void) {}

/* Runs the plant; acc_m[i] = the motor's acceleration at sample i. */
static size_t simulate(const char *text)
{
    size_t n = sim_run(&plant, text, run, MAXN);
    for (size_t i = 0; i < n; i++) {
        double a, v;
        hd_sim_motor_kinematics(&plant, run[i].t_s, &a, &v, &acc_m[i]);
    }
    return n;
}

static double sgn(double x)
{
    return (x > 0.0) - (x < 0.0);
}

/* An arm swinging +-1 rad of output angle at 100:1, m g l 12 N m, a 3 N m
 * payload picked up at 2 s (over 0.1 s). */
static const char *ARM = "duration_s = 4\n"
                         "load_inertia_kgm2 = 0\nviscous_nm_s_rad = 0\ncoulomb_nm = 0\n"
                         "motor_speed_profile = 0:0, 0.5:150, 1.5:-150, 2.5:150, 3.5:-150\n"
                         "gravity_profile = 0:12, 2:12, 2.1:15\n"
                         "gravity_phase_rad = 0.4\n";

static void test_gravity_with_a_payload_change(void)
{
    size_t n = simulate(ARM);
    TEST_ASSERT_EQUAL_UINT(4000, n);
    for (size_t k = 0; k < n; k += 7) {
        const hd_sim_sample_t *s = &run[k];
        double mgl = s->t_s < 2.0 ? 12.0 : (s->t_s >= 2.1 ? 15.0 : 12.0 + 30.0 * (s->t_s - 2.0));
        double expect = mgl * sin(s->motor_angle_rad / 100.0 + 0.4);
        TEST_ASSERT_DOUBLE_WITHIN(1e-9, expect, s->torque_true_nm);
        TEST_ASSERT_DOUBLE_WITHIN(1e-9, expect, s->gravity_nm);
    }
}

static void test_slow_sine_loads_add_to_the_profile(void)
{
    size_t n = simulate("duration_s = 3\nload_inertia_kgm2 = 0\nviscous_nm_s_rad = 0\n"
                        "coulomb_nm = 0\nmotor_speed_profile = 0:30\n"
                        "load_torque_profile = 0:1, 3:4\n"
                        "load_sine = 2 : 5 : 0.3\nload_sine = 0.5 : 60 : -1\n");
    for (size_t k = 0; k < n; k += 11) {
        double t = run[k].t_s;
        double expect = 1.0 + t + 2.0 * sin(2.0 * PI_D * t / 5.0 + 0.3) +
                        0.5 * sin(2.0 * PI_D * t / 60.0 - 1.0);
        TEST_ASSERT_DOUBLE_WITHIN(1e-9, expect, run[k].torque_true_nm);
        TEST_ASSERT_DOUBLE_WITHIN(1e-9, expect, run[k].load_torque_nm);
    }
}

static void test_feedforward_is_the_controllers_own_model(void)
{
    char text[2048];
    /* told everything exactly: the feed-forward is the truth */
    snprintf(text, sizeof text,
             "duration_s = 4\n%sload_inertia_kgm2 = 0.2\nviscous_nm_s_rad = 0.5\n"
             "coulomb_nm = 0.7\nload_torque_profile = 0:0, 4:2\n"
             "feedforward = 1\nfeedforward.load_scale = 1\nfeedforward.inertia_kgm2 = 0.2\n"
             "feedforward.viscous_nm_s_rad = 0.5\nfeedforward.coulomb_nm = 0.7\n",
             strstr(ARM, "motor_speed_profile"));
    size_t n = simulate(text);
    for (size_t k = 0; k < n; k++) {
        TEST_ASSERT_DOUBLE_WITHIN(1e-9, run[k].torque_true_nm, run[k].feedforward_nm);
        TEST_ASSERT_TRUE(run[k].feedforward_sent);
    }
    /* its own errors: payload 10 % light, 0.05 rad posture error, J 30 % off,
     * no external load, a frame every 4 ms, none in [1, 1.5) s */
    snprintf(text, sizeof text,
             "duration_s = 4\n%sload_inertia_kgm2 = 0.2\nviscous_nm_s_rad = 0\n"
             "coulomb_nm = 0\nload_torque_profile = 0:0, 4:2\n"
             "feedforward = 1\nfeedforward.gravity_scale = 0.9\n"
             "feedforward.gravity_phase_error_rad = 0.05\nfeedforward.inertia_kgm2 = 0.14\n"
             "feedforward.period_ms = 4\nfeedforward.dropout = 1:1.5\n",
             strstr(ARM, "motor_speed_profile"));
    n = simulate(text);
    unsigned sent = 0;
    for (size_t k = 0; k < n; k++) {
        const hd_sim_sample_t *s = &run[k];
        double expect = 0.9 * (s->gravity_nm / sin(s->output_angle_rad + 0.4)) *
                            sin(s->output_angle_rad + 0.45) +
                        0.14 * s->output_accel_rad_s2;
        if (fabs(sin(s->output_angle_rad + 0.4)) > 0.05) {
            TEST_ASSERT_DOUBLE_WITHIN(1e-9, expect, s->feedforward_nm);
        }
        bool want = k % 4 == 0 && !(s->t_s >= 1.0 && s->t_s < 1.5);
        TEST_ASSERT_EQUAL(want, s->feedforward_sent);
        sent += s->feedforward_sent;
    }
    TEST_ASSERT_EQUAL_UINT(875, sent);
}

/* The current, inverted through the documented model, gives back the
 * transmitted torque: k_i i - J_r a_o - b_r w_o - Fc_r sgn = T_true with
 * k_i = N eta kt_true (motoring), N kt_true / eta_b (back-driven), and
 * J_r = N^2 J_m, b_r = N^2 b_m, Fc_r = N Fc_m (each times the same factor). */
static void test_motor_current_follows_the_drive_model(void)
{
    char text[2048];
    snprintf(text, sizeof text,
             "duration_s = 4\n%sload_inertia_kgm2 = 0.1\nviscous_nm_s_rad = 0.3\n"
             "coulomb_nm = 0.5\n"
             "motor.kt_nm_per_a = 0.09\nmotor.kt_error = 0.08\nmotor.efficiency = 0.8\n"
             "motor.backdrive_efficiency = 0.7\nmotor.coulomb_nm = 0.012\n"
             "motor.viscous_nm_s_rad = 1e-5\nmotor.inertia_kgm2 = 3e-5\n",
             strstr(ARM, "motor_speed_profile"));
    size_t n = simulate(text);
    const double N = 100.0, kt = 0.09 * 1.08;
    unsigned motoring = 0, driven = 0;
    for (size_t k = 1; k < n; k++) {
        const hd_sim_sample_t *s = &run[k];
        const double wm = s->motor_velocity_rad_s;
        const double motor_side = 3e-5 * acc_m[k] + 1e-5 * wm + 0.012 * sgn(wm);
        const double gear = s->motor_current_a * kt - motor_side; /* what the gear takes */
        const bool mot = s->torque_true_nm * s->output_velocity_rad_s >= 0.0;
        const double back = mot ? gear * N * 0.8 : gear * N / 0.7;
        TEST_ASSERT_DOUBLE_WITHIN(1e-7 * (1.0 + fabs(s->torque_true_nm)), s->torque_true_nm, back);
        motoring += mot;
        driven += !mot;
    }
    TEST_ASSERT_TRUE(motoring > 500 && driven > 500); /* both directions of power flow */
}

static void test_current_noise_has_its_std(void)
{
    static hd_sim_sample_t clean[MAXN];
    const char *base = "duration_s = 5\nmotor_speed_profile = 0:50\nmotor.kt_nm_per_a = 0.1\n";
    size_t m = simulate(base);
    memcpy(clean, run, sizeof(hd_sim_sample_t) * m);
    char text[256];
    snprintf(text, sizeof text, "%smotor.current_noise_a = 0.02\n", base);
    size_t n = simulate(text);
    TEST_ASSERT_EQUAL_UINT(m, n);
    double s2 = 0.0;
    for (size_t k = 0; k < n; k++) {
        double d = run[k].motor_current_a - clean[k].motor_current_a;
        TEST_ASSERT_EQUAL_DOUBLE(clean[k].torque_nm, run[k].torque_nm); /* sensor stream kept */
        s2 += d * d;
    }
    /* 5000 draws: the sample std is within 1 % (1 sigma) of 0.02; 5 % is 5 sigma */
    TEST_ASSERT_DOUBLE_WITHIN(0.02 * 0.05, 0.02, sqrt(s2 / (double)n));
}

static void test_nothing_new_without_the_keys(void)
{
    size_t n = simulate("duration_s = 1\n");
    for (size_t k = 0; k < n; k++) {
        TEST_ASSERT_TRUE(isnan(run[k].feedforward_nm));
        TEST_ASSERT_TRUE(isnan(run[k].motor_current_a));
        TEST_ASSERT_FALSE(run[k].feedforward_sent);
        TEST_ASSERT_EQUAL_DOUBLE(0.0, run[k].gravity_nm);
    }
    /* the HAL has a current channel only with a motor */
    static hal_sim_t sim;
    hal_t hal;
    memset(&hal, 0, sizeof hal);
    hd_sim_scenario_t sc;
    hd_sim_scenario_default(&sc);
    TEST_ASSERT_EQUAL_INT(0, hal_sim_init(&sim, &sc, err, sizeof err));
    hal_sim_bind(&sim, &hal);
    TEST_ASSERT_NULL(hal.sensors.current_read);
    TEST_ASSERT_EQUAL_INT(0, hd_sim_scenario_set(&sc, "motor.kt_nm_per_a", "0.1", err, sizeof err));
    TEST_ASSERT_EQUAL_INT(0, hal_sim_init(&sim, &sc, err, sizeof err));
    hal_sim_bind(&sim, &hal);
    TEST_ASSERT_NOT_NULL(hal.sensors.current_read);
    hal_adc_sample_t a;
    hal_current_sample_t c;
    TEST_ASSERT_EQUAL_INT(HAL_OK, hal.sensors.adc_read(hal.sensors.ctx, &a));
    TEST_ASSERT_EQUAL_INT(HAL_OK, hal.sensors.current_read(hal.sensors.ctx, &c));
    TEST_ASSERT_EQUAL_FLOAT((float)hal_sim_current(&sim)->motor_current_a, c.motor_current_a);
}

/* Each refused for its own reason: the message names the file and the key. */
static void test_bad_values_are_refused(void)
{
    const struct {
        const char *text;
        const char *key;
    } bad[] = {
        {"feedforward = 2\n", "feedforward must"},
        {"feedforward.period_ms = 0\n", "feedforward.period_ms"},
        {"motor.efficiency = 1.5\n", "motor.efficiency"},
        {"motor.efficiency = 0\n", "motor.efficiency"},
        {"motor.kt_error = -1\n", "motor.kt_error"},
        {"load_sine = 1 : 0 : 0\n", "load_sine"},
        {"load_sine = 1 : 5\n", "load_sine"},
        {"feedforward.dropout = 2:1\n", "feedforward.dropout"},
        {"motor.kt_nm_per_a = -0.1\n", "motor.kt_nm_per_a"},
        {"gravity_profile = 1:2, 0.5:3\n", "gravity_profile"},
    };
    for (unsigned i = 0; i < sizeof bad / sizeof bad[0]; i++) {
        hd_sim_scenario_t sc;
        hd_sim_scenario_default(&sc);
        err[0] = '\0';
        TEST_ASSERT_EQUAL_INT_MESSAGE(-1, hd_sim_scenario_parse(&sc, bad[i].text, "t", err,
                                                                sizeof err),
                                      bad[i].text);
        if (strncmp(err, "t:", 2) != 0 || strstr(err, bad[i].key) == NULL) {
            TEST_FAIL_MESSAGE(err);
        }
    }
}

int main(int argc, char **argv)
{
    if (UnityParseOptions(argc, argv) != 0) {
        return 1;
    }
    UNITY_BEGIN();
    RUN_TEST(test_gravity_with_a_payload_change);
    RUN_TEST(test_slow_sine_loads_add_to_the_profile);
    RUN_TEST(test_feedforward_is_the_controllers_own_model);
    RUN_TEST(test_motor_current_follows_the_drive_model);
    RUN_TEST(test_current_noise_has_its_std);
    RUN_TEST(test_nothing_new_without_the_keys);
    RUN_TEST(test_bad_values_are_refused);
    return UNITY_END();
}
