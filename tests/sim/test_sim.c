/* Simulated joint (hal/sim): plant, scenario parser and HAL backend against
 * closed forms computed here independently of the plant's code paths. */
#include <math.h>
#include <stdio.h>
#include <stdlib.h>
#include <string.h>

#include "hal_sim.h"
#include "hd_sim_plant.h"
#include "hd_sim_scenario.h"
#include "sim_run.h"
#include "unity.h"

#define PI_D 3.14159265358979323846
#define MAXN 40000

static hd_sim_plant_t plant;
static hd_sim_sample_t run[MAXN];
static char err[512];

void setUp(void) {}
void tearDown(void) {}

/* Parses text on top of the defaults, runs the plant, returns the count. */
static size_t simulate(const char *text)
{
    return sim_run(&plant, text, run, MAXN);
}

/* Least squares of x = a sin(arg) + b cos(arg) + c over samples [i0, i1). */
static void fit_line(size_t i0, size_t i1, const double *arg, const double *x,
                     double *amp, double *phase, double *mean)
{
    /* Normal equations, 3x3, solved by Cramer's rule. */
    double m[3][3] = {{0}}, r[3] = {0};
    for (size_t i = i0; i < i1; i++) {
        const double f[3] = {sin(arg[i]), cos(arg[i]), 1.0};
        for (int j = 0; j < 3; j++) {
            r[j] += f[j] * x[i];
            for (int k = 0; k < 3; k++) {
                m[j][k] += f[j] * f[k];
            }
        }
    }
    const double det = m[0][0] * (m[1][1] * m[2][2] - m[1][2] * m[2][1]) -
                       m[0][1] * (m[1][0] * m[2][2] - m[1][2] * m[2][0]) +
                       m[0][2] * (m[1][0] * m[2][1] - m[1][1] * m[2][0]);
    double sol[3];
    for (int c = 0; c < 3; c++) {
        double mm[3][3];
        memcpy(mm, m, sizeof(mm));
        for (int j = 0; j < 3; j++) {
            mm[j][c] = r[j];
        }
        sol[c] = (mm[0][0] * (mm[1][1] * mm[2][2] - mm[1][2] * mm[2][1]) -
                  mm[0][1] * (mm[1][0] * mm[2][2] - mm[1][2] * mm[2][0]) +
                  mm[0][2] * (mm[1][0] * mm[2][1] - mm[1][1] * mm[2][0])) / det;
    }
    /* a sin + b cos = A sin(arg + phi): a = A cos phi, b = A sin phi */
    *amp = hypot(sol[0], sol[1]);
    *phase = atan2(sol[1], sol[0]);
    *mean = sol[2];
}

static double xbuf[MAXN], abuf[MAXN];

/* ------------------------------------------------------------------ kinematics, encoders */

static void test_encoder_counts_follow_prescribed_angle(void)
{
    /* speed 0 -> 10 rad/s over 1 s, then held: theta = 5 t^2, then 5 + 10 (t - 1). */
    size_t n = simulate("duration_s = 3\nmotor_speed_profile = 0:0, 1:10\n"
                        "motor_angle0_rad = 0.25\nencoder_cpr = 1000\noutput_encoder_cpr = 5000\n"
                        "gear_ratio = 50\n");
    TEST_ASSERT_EQUAL_UINT(3000, n);
    for (size_t i = 0; i < n; i++) {
        const double t = 0.001 * (double)i;
        const double th = 0.25 + (t < 1.0 ? 5.0 * t * t : 5.0 + 10.0 * (t - 1.0));
        TEST_ASSERT_DOUBLE_WITHIN(1e-9, th, run[i].motor_angle_rad);
        TEST_ASSERT_DOUBLE_WITHIN(1e-9, t < 1.0 ? 10.0 * t : 10.0, run[i].motor_velocity_rad_s);
        /* Skip samples within 1e-9 count of an edge, where rounding may differ. */
        const double c = th * 1000.0 / (2.0 * PI_D);
        if (fabs(c - floor(c + 0.5)) > 1e-6) {
            TEST_ASSERT_EQUAL_UINT32((uint32_t)floor(c), run[i].motor_counts);
        }
        const double co = th / 50.0 * 5000.0 / (2.0 * PI_D);
        if (fabs(co - floor(co + 0.5)) > 1e-6) {
            TEST_ASSERT_EQUAL_UINT32((uint32_t)floor(co), run[i].output_counts);
        }
        TEST_ASSERT_TRUE(run[i].has_output);
    }
}

static void test_output_angle_is_motor_over_ratio(void)
{
    size_t n = simulate("duration_s = 2\nmotor_speed_profile = 0:50, 1:-80, 1.5:20\ngear_ratio = 160\n");
    for (size_t i = 0; i < n; i++) {
        TEST_ASSERT_DOUBLE_WITHIN(1e-12, run[i].motor_angle_rad / 160.0, run[i].output_angle_rad);
        TEST_ASSERT_DOUBLE_WITHIN(1e-12, run[i].motor_velocity_rad_s / 160.0,
                                  run[i].output_velocity_rad_s);
        TEST_ASSERT_FALSE(run[i].has_output);
        TEST_ASSERT_EQUAL_UINT32(0, run[i].output_counts);
    }
}

static void test_encoder_counts_wrap_below_zero(void)
{
    /* Negative angles count down from 2^32 like a free-running counter. */
    simulate("duration_s = 0.01\nmotor_speed_profile = 0:0\nmotor_angle0_rad = -1\n"
             "encoder_cpr = 1000\n");
    const double c = floor(-1000.0 / (2.0 * PI_D)); /* -160 */
    TEST_ASSERT_EQUAL_UINT32((uint32_t)(4294967296.0 + c), run[0].motor_counts);
}

/* ------------------------------------------------------------------ truth */

static void test_truth_is_rigid_body_plus_friction_plus_load_without_ripple(void)
{
    size_t n = simulate("duration_s = 4\nmotor_speed_profile = 0:0, 1:100, 2:100, 3:-100\n"
                        "load_torque_profile = 0:0, 4:8\nload_inertia_kgm2 = 0.2\n"
                        "viscous_nm_s_rad = 0.7\ncoulomb_nm = 1.3\n"
                        "ripple = motor : 2 : 2.0 : 0\nripple = output : 1 : 1.0 : 0\n"
                        "offset_nm = 0.5\nnoise_nm = 0.1\n");
    for (size_t i = 0; i < n; i++) {
        const double t = 0.001 * (double)i;
        /* motor acceleration: 100, 0, -200 rad/s^2 on the three segments, 0 after */
        const double acc_m = t < 1.0 ? 100.0 : (t < 2.0 ? 0.0 : (t < 3.0 ? -200.0 : 0.0));
        const double vel_m = t < 1.0 ? 100.0 * t : (t < 2.0 ? 100.0 : (t < 3.0 ? 100.0 - 200.0 * (t - 2.0) : -100.0));
        const double w = vel_m / 100.0;
        const double sg = w > 0.0 ? 1.0 : (w < 0.0 ? -1.0 : 0.0);
        const double truth = 0.2 * acc_m / 100.0 + 0.7 * w + 1.3 * sg + 2.0 * t;
        if (fabs(w) > 1e-9) { /* the sign at exact zero speed is a convention */
            TEST_ASSERT_DOUBLE_WITHIN(1e-9, truth, run[i].torque_true_nm);
        }
    }
}

/* ------------------------------------------------------------------ ripple lines */

static void test_motor_ripple_line_amplitude_phase_and_frequency(void)
{
    /* 100 rad/s: the order-2 line is at 200 rad/s.  No bridge modulation. */
    size_t n = simulate("duration_s = 3\nmotor_speed_profile = 0:100\nbridge.psi0 = 0\n"
                        "load_torque_profile = 0:2\nripple = motor : 2 : 0.7 : 0.4\n");
    for (size_t i = 0; i < n; i++) {
        xbuf[i] = run[i].ripple_true_nm;
        abuf[i] = 2.0 * run[i].motor_angle_rad;
    }
    double amp, ph, mean;
    fit_line(0, n, abuf, xbuf, &amp, &ph, &mean);
    TEST_ASSERT_DOUBLE_WITHIN(1e-5, 0.7, amp);
    TEST_ASSERT_DOUBLE_WITHIN(1e-5, 0.4, ph);
    TEST_ASSERT_DOUBLE_WITHIN(1e-5, 0.0, mean);

    /* Frequency: the DFT peak of the measured torque over 150..250 rad/s. */
    double best_w = 0.0, best_p = 0.0;
    for (double wq = 150.0; wq <= 250.0; wq += 0.05) {
        double re = 0.0, im = 0.0;
        for (size_t i = 0; i < n; i++) {
            const double t = 0.001 * (double)i;
            re += (run[i].torque_nm - 2.0) * cos(wq * t);
            im += (run[i].torque_nm - 2.0) * sin(wq * t);
        }
        if (re * re + im * im > best_p) {
            best_p = re * re + im * im;
            best_w = wq;
        }
    }
    TEST_ASSERT_DOUBLE_WITHIN(0.1, 200.0, best_w);
    /* Measured torque carries the same line, to within ADC quantisation. */
    for (size_t i = 0; i < n; i++) {
        xbuf[i] = run[i].torque_nm - run[i].torque_true_nm;
    }
    fit_line(0, n, abuf, xbuf, &amp, &ph, &mean);
    TEST_ASSERT_DOUBLE_WITHIN(2e-3, 0.7, amp);
}

static void test_output_and_fixed_lines(void)
{
    /* misalignment at output order 1 (output at 2 rad/s) and 50 Hz pickup */
    size_t n = simulate("duration_s = 4\nmotor_speed_profile = 0:200\nbridge.psi0 = 0\n"
                        "ripple = output : 1 : 0.5 : -0.7\nripple = fixed : 50 : 0.1 : 0.2\n");
    for (size_t i = 0; i < n; i++) {
        abuf[i] = run[i].motor_angle_rad / 100.0;
        xbuf[i] = run[i].ripple_true_nm - 0.1 * sin(2.0 * PI_D * 50.0 * 0.001 * (double)i + 0.2);
    }
    double amp, ph, mean;
    fit_line(0, n, abuf, xbuf, &amp, &ph, &mean);
    TEST_ASSERT_DOUBLE_WITHIN(1e-5, 0.5, amp);
    TEST_ASSERT_DOUBLE_WITHIN(1e-5, -0.7, ph);
    for (size_t i = 0; i < n; i++) {
        abuf[i] = 2.0 * PI_D * 50.0 * 0.001 * (double)i;
        xbuf[i] = run[i].ripple_true_nm - 0.5 * sin(run[i].motor_angle_rad / 100.0 - 0.7);
    }
    fit_line(0, n, abuf, xbuf, &amp, &ph, &mean);
    TEST_ASSERT_DOUBLE_WITHIN(1e-5, 0.1, amp);
    TEST_ASSERT_DOUBLE_WITHIN(1e-4, 0.2, ph);
}

static void test_ripple_grows_with_load_when_enabled(void)
{
    /* amplitude = A (1 + c |T_true|); T_true = 0 + 1 (viscous at 1 rad/s) + 1 (Coulomb) + 8 load = 10 */
    size_t n = simulate("duration_s = 2\nmotor_speed_profile = 0:100\nbridge.psi0 = 0\n"
                        "load_torque_profile = 0:8\nripple = motor : 4 : 0.3 : 0\n"
                        "ripple_load_coeff_per_nm = 0.05\n");
    TEST_ASSERT_DOUBLE_WITHIN(1e-9, 10.0, run[10].torque_true_nm);
    for (size_t i = 0; i < n; i++) {
        abuf[i] = 4.0 * run[i].motor_angle_rad;
        xbuf[i] = run[i].ripple_true_nm;
    }
    double amp, ph, mean;
    fit_line(0, n, abuf, xbuf, &amp, &ph, &mean);
    TEST_ASSERT_DOUBLE_WITHIN(1e-5, 0.3 * 1.5, amp);
}

static void test_offset_drift_is_linear_in_time(void)
{
    size_t n = simulate("duration_s = 2\nmotor_speed_profile = 0:0\nbridge.psi0 = 0\n"
                        "offset_nm = 0.2\noffset_drift_nm_per_s = 0.05\n");
    for (size_t i = 0; i < n; i += 97) {
        TEST_ASSERT_DOUBLE_WITHIN(1e-6, 0.2 + 0.05 * 0.001 * (double)i, run[i].ripple_true_nm);
    }
}

/* ------------------------------------------------------------------ bridge in the plant */

static void test_bridge_placement_error_gives_predicted_2x_line(void)
{
    /* psi0 = 4e-5 strain, S = 0.002 - (-0.001) + 0 - 0 = 3 mrad.
     * First order: line = -(psi0 S / 4) / strain_per_nm cos(2 beta) in N m,
     * strain_per_nm = 1/(6.6*2*10*1000): amplitude 4e-5*3e-3/4*132000 = 3.96e-3 N m
     * ... scaled up by a large psi0 so it stands far above float resolution. */
    size_t n = simulate("duration_s = 1\nmotor_speed_profile = 0:100\nload_torque_profile = 0:2\n"
                        "bridge.psi0 = 1e-3\nbridge.placement_error_rad = 0.002, -0.001, 0, 0\n");
    const double expect = 1e-3 * 3e-3 / 4.0 * (6.6 * 2.0 * 10.0 * 1000.0); /* 0.099 N m */
    for (size_t i = 0; i < n; i++) {
        abuf[i] = 2.0 * run[i].motor_angle_rad;
        xbuf[i] = run[i].ripple_true_nm;
    }
    double amp, ph, mean;
    fit_line(0, n, abuf, xbuf, &amp, &ph, &mean);
    TEST_ASSERT_DOUBLE_WITHIN(0.01 * expect, expect, amp);
    /* -cos(x) = sin(x - pi/2) */
    TEST_ASSERT_DOUBLE_WITHIN(0.01, -PI_D / 2.0, ph);

    /* Ideal placement: the same huge psi0 cancels exactly (eq 4). */
    n = simulate("duration_s = 1\nmotor_speed_profile = 0:100\nload_torque_profile = 0:2\n"
                 "bridge.psi0 = 1e-3\n");
    for (size_t i = 0; i < n; i++) {
        TEST_ASSERT_DOUBLE_WITHIN(2e-5, 0.0, run[i].ripple_true_nm);
    }
}

/* ------------------------------------------------------------------ ADC */

static void test_adc_quantises_clips_and_flags_saturation(void)
{
    /* Nominal 6.6 N m/V over +-10 V: rails at +-66 N m.  Ramp -100..100 N m. */
    size_t n = simulate("duration_s = 2\nmotor_speed_profile = 0:0\ncoulomb_nm = 0\n"
                        "load_torque_profile = 0:-100, 2:100\nbridge.psi0 = 0\nadc_bits = 12\n");
    const double lsb = 20.0 / 4096.0;
    size_t sat = 0;
    for (size_t i = 0; i < n; i++) {
        const double t_nm = -100.0 + 100.0 * 0.001 * (double)i;
        TEST_ASSERT_DOUBLE_WITHIN(1e-9, t_nm, run[i].torque_true_nm);
        const double code = floor(t_nm / 6.6 / lsb + 0.5);
        if (code >= 2047.0) {
            TEST_ASSERT_EQUAL_INT32(2047, run[i].bridge_counts);
            TEST_ASSERT_TRUE(run[i].saturated);
            sat++;
        } else if (code <= -2048.0) {
            TEST_ASSERT_EQUAL_INT32(-2048, run[i].bridge_counts);
            TEST_ASSERT_TRUE(run[i].saturated);
            sat++;
        } else if (fabs(t_nm / 6.6 / lsb - code) < 0.499) { /* away from a code edge */
            TEST_ASSERT_EQUAL_INT32((int32_t)code, run[i].bridge_counts);
            TEST_ASSERT_FALSE(run[i].saturated);
            TEST_ASSERT_DOUBLE_WITHIN(0.5 * lsb * 6.6 + 1e-6, t_nm, run[i].torque_nm);
        }
    }
    /* |T| > 66 N m for 2 * 34/100 of the run */
    TEST_ASSERT_INT_WITHIN(4, 680, (int64_t)sat);
}

/* ------------------------------------------------------------------ noise and determinism */

static double std_of_error(size_t n)
{
    double s = 0.0, s2 = 0.0;
    for (size_t i = 0; i < n; i++) {
        const double e = run[i].torque_nm - run[i].torque_true_nm;
        s += e;
        s2 += e * e;
    }
    const double m = s / (double)n;
    return sqrt(s2 / (double)n - m * m);
}

static void test_noise_std_matches(void)
{
    const double lsb_nm = 20.0 / 65536.0 * 6.6; /* quantisation adds lsb^2/12 */
    size_t n = simulate("duration_s = 40\nmotor_speed_profile = 0:0\nbridge.psi0 = 0\n"
                        "load_torque_profile = 0:1\nnoise_nm = 0.05\n");
    TEST_ASSERT_EQUAL_UINT(40000, n);
    double expect = sqrt(0.05 * 0.05 + lsb_nm * lsb_nm / 12.0);
    TEST_ASSERT_DOUBLE_WITHIN(0.02 * expect, expect, std_of_error(n));
    /* noise in volts at the amplifier output: 2 mV = 13.2 mN m */
    n = simulate("duration_s = 40\nmotor_speed_profile = 0:0\nbridge.psi0 = 0\n"
                 "load_torque_profile = 0:1\nnoise_v = 0.002\n");
    expect = sqrt(0.002 * 6.6 * 0.002 * 6.6 + lsb_nm * lsb_nm / 12.0);
    TEST_ASSERT_DOUBLE_WITHIN(0.02 * expect, expect, std_of_error(n));
}

static void test_same_seed_same_run_other_seed_differs(void)
{
    static int32_t first[5000];
    const char *base = "duration_s = 5\nnoise_nm = 0.05\noffset_random_walk_nm_per_sqrt_s = 0.01\n";
    char text[256];
    snprintf(text, sizeof(text), "%sseed = 7\n", base);
    size_t n = simulate(text);
    for (size_t i = 0; i < n; i++) {
        first[i] = run[i].bridge_counts;
    }
    simulate(text);
    size_t diff = 0;
    for (size_t i = 0; i < n; i++) {
        diff += first[i] != run[i].bridge_counts;
    }
    TEST_ASSERT_EQUAL_UINT(0, diff);
    snprintf(text, sizeof(text), "%sseed = 8\n", base);
    simulate(text);
    for (size_t i = 0; i < n; i++) {
        diff += first[i] != run[i].bridge_counts;
    }
    TEST_ASSERT_GREATER_THAN(n / 2, diff);
}

/* ------------------------------------------------------------------ parser */

static void expect_reject(const char *text, const char *needle)
{
    hd_sim_scenario_t sc;
    hd_sim_scenario_default(&sc);
    err[0] = '\0';
    TEST_ASSERT_EQUAL_INT(-1, hd_sim_scenario_parse(&sc, text, "bad.ini", err, sizeof(err)));
    if (strstr(err, needle) == NULL) {
        char msg[700];
        snprintf(msg, sizeof(msg), "expected \"%s\" in \"%s\"", needle, err);
        TEST_FAIL_MESSAGE(msg);
    }
}

static void test_parser_rejects_with_line_numbers(void)
{
    expect_reject("# c\nduration_s = 1\nfoo = 3\n", "bad.ini:3: unknown key \"foo\"");
    expect_reject("gear_ratio = 10x\n", "bad.ini:1: gear_ratio:");
    expect_reject("\n\ngear_ratio = -5\n", "bad.ini:3: gear_ratio: must be > 0");
    expect_reject("seed = 1\nseed = 2\n", "bad.ini:2: seed given twice");
    expect_reject("duration_s 5\n", "bad.ini:1: expected \"key = value\"");
    expect_reject("ripple = motor : 2 : 1.0\n", "bad.ini:1: ripple: expected");
    expect_reject("ripple = gear : 2 : 1.0 : 0\n", "unknown kind \"gear\"");
    expect_reject("ripple = motor : 2 : -1.0 : 0\n", "amplitude must be");
    expect_reject("motor_speed_profile = 0:0, 2:5, 1:3\n", "bad.ini:1: motor_speed_profile: profile point 3");
    expect_reject("load_torque_profile = 0:0, 1\n", "profile point 2: expected");
    expect_reject("noise_nm = nan\n", "not a finite number");
    expect_reject("adc_bits = 40\n", "adc_bits must be in [8, 24]");
    expect_reject("bridge.placement_error_rad = 0.1, 0.2\n", "expected 4");
    expect_reject("encoder_cpr = 0\n", "encoder_cpr must be >= 1");
    expect_reject("ts_s = 0.0000005\n", "whole number of microseconds");
    expect_reject("noise_nm =\n", "empty value");
    /* integers are decimal: a leading zero is not octal, no hex, no sign */
    expect_reject("encoder_cpr = 01024\n", "bad.ini:1: encoder_cpr: \"01024\" has a leading zero");
    expect_reject("seed = 0x10\n", "seed: \"0x10\" is not a non-negative decimal integer");
    expect_reject("adc_bits = +16\n", "is not a non-negative decimal integer");
    expect_reject("seed = 18446744073709551616\n", "is not a non-negative decimal integer");
    expect_reject("noise_nm = 0x1p-3\n", "not a finite number");
    /* a repeated key names both lines */
    expect_reject("duration_s = 1\n# c\nduration_s = 2\n", "bad.ini:3: duration_s given twice (first on line 1)");
    /* bytes that are not text, with their line */
    expect_reject("duration_s = 1\nnoise_nm = 0.1\x01\n", "bad.ini:2: control character 0x01");
    expect_reject("# caf\xe9\n", "bad.ini:1: byte 0xE9 is not UTF-8 text");
    expect_reject("# ok\n# \xc3\n", "bad.ini:2: byte 0xC3 is not UTF-8 text");
}

static void test_parser_rejects_nul_with_its_line(void)
{
    static const char text[] = "duration_s = 1\nnoise_nm = 0.1\0node_id = 999\n";
    hd_sim_scenario_t sc;
    hd_sim_scenario_default(&sc);
    TEST_ASSERT_EQUAL_INT(-1, hd_sim_scenario_parse_n(&sc, text, sizeof text - 1u, "nul.ini",
                                                      err, sizeof(err)));
    if (strstr(err, "nul.ini:2: NUL byte at column 15") == NULL) {
        TEST_FAIL_MESSAGE(err);
    }
    /* UTF-8 in a comment is text */
    hd_sim_scenario_default(&sc);
    TEST_ASSERT_EQUAL_INT_MESSAGE(0, hd_sim_scenario_parse(&sc, "# caf\xc3\xa9 \xe2\x82\xac\n"
                                                           "duration_s = 1\n", "u", err,
                                                           sizeof(err)), err);
    TEST_ASSERT_EQUAL_UINT64(1000, hd_sim_scenario_samples(&sc));
}

static void test_parser_accepts_comments_quotes_and_lists(void)
{
    hd_sim_scenario_t sc;
    hd_sim_scenario_default(&sc);
    const char *text = "  # comment\n\nmotor_speed_profile = \"0:0, 0.5:156\"  # trailing\n"
                       "ripple = motor:2:1.0:0.3\nripple = output : 1 : 0.5 : -0.7\n"
                       "bridge.placement_error_rad = 0.001, -0.0005, 0.0008, 0.0002\n"
                       "seed = 16\n";
    TEST_ASSERT_EQUAL_INT_MESSAGE(0, hd_sim_scenario_parse(&sc, text, "ok", err, sizeof(err)), err);
    TEST_ASSERT_EQUAL_UINT(2, sc.motor_speed.n);
    TEST_ASSERT_DOUBLE_WITHIN(1e-12, 156.0, sc.motor_speed.value[1]);
    TEST_ASSERT_EQUAL_UINT(2, sc.ripple_count);
    TEST_ASSERT_EQUAL_INT(HD_SIM_RIPPLE_OUTPUT, sc.ripples[1].kind);
    TEST_ASSERT_DOUBLE_WITHIN(1e-12, -0.7, sc.ripples[1].phase_rad);
    TEST_ASSERT_FLOAT_WITHIN(1e-9, -0.0005, sc.bridge.placement_error_rad[1]);
    TEST_ASSERT_EQUAL_UINT64(16, sc.seed);
    TEST_ASSERT_EQUAL_INT(0, hd_sim_scenario_set(&sc, "duration_s", "2.5", err, sizeof(err)));
    TEST_ASSERT_EQUAL_UINT64(2500, hd_sim_scenario_samples(&sc));
    TEST_ASSERT_EQUAL_INT(-1, hd_sim_scenario_set(&sc, "nope", "1", err, sizeof(err)));
}

static void test_missing_file_is_a_clear_error(void)
{
    hd_sim_scenario_t sc;
    hd_sim_scenario_default(&sc);
    TEST_ASSERT_EQUAL_INT(-1, hd_sim_scenario_load(&sc, "/nonexistent/x.ini", err, sizeof(err)));
    TEST_ASSERT_NOT_NULL(strstr(err, "/nonexistent/x.ini: cannot open"));
}

/* ------------------------------------------------------------------ HAL backend */

static void test_hal_backend_ticks_and_ends(void)
{
    hd_sim_scenario_t sc;
    hd_sim_scenario_default(&sc);
    TEST_ASSERT_EQUAL_INT(0, hd_sim_scenario_parse(&sc, "duration_s = 0.01\nencoder_cpr = 1000\n"
                                                   "noise_nm = 0.01\n", "t", err, sizeof(err)));
    static hal_sim_t sim;
    TEST_ASSERT_EQUAL_INT(0, hal_sim_init(&sim, &sc, err, sizeof(err)));
    hd_sim_plant_t ref; /* an independent plant run of the same scenario */
    TEST_ASSERT_EQUAL_INT(0, hd_sim_plant_init(&ref, &sc, err, sizeof(err)));
    hal_t hal = {0};
    hal_sim_bind(&sim, &hal);
    TEST_ASSERT_NULL(hal_sim_current(&sim));
    hal_adc_sample_t a;
    hal_encoder_sample_t e;
    hd_sim_sample_t s;
    for (int k = 0; k < 10; k++) {
        /* alternate the read order: either order is one tick */
        if (k % 2 == 0) {
            TEST_ASSERT_EQUAL_INT(HAL_OK, hal.sensors.adc_read(hal.sensors.ctx, &a));
            TEST_ASSERT_EQUAL_INT(HAL_OK, hal.sensors.encoder_read(hal.sensors.ctx, &e));
        } else {
            TEST_ASSERT_EQUAL_INT(HAL_OK, hal.sensors.encoder_read(hal.sensors.ctx, &e));
            TEST_ASSERT_EQUAL_INT(HAL_OK, hal.sensors.adc_read(hal.sensors.ctx, &a));
        }
        TEST_ASSERT_EQUAL_INT(0, hd_sim_plant_next(&ref, &s));
        TEST_ASSERT_EQUAL_INT32(s.bridge_counts, a.bridge_counts);
        TEST_ASSERT_EQUAL_UINT32(s.motor_counts, e.motor_counts);
        TEST_ASSERT_EQUAL_UINT64((uint64_t)k * 1000u, hal.clock.time_us(hal.clock.ctx));
        const hd_sim_sample_t *cur = hal_sim_current(&sim);
        TEST_ASSERT_NOT_NULL(cur);
        TEST_ASSERT_DOUBLE_WITHIN(1e-12, s.torque_true_nm, cur->torque_true_nm);
    }
    TEST_ASSERT_EQUAL_INT(HAL_ERR_END, hal.sensors.adc_read(hal.sensors.ctx, &a));
    TEST_ASSERT_EQUAL_INT(HAL_ERR_END, hal.sensors.encoder_read(hal.sensors.ctx, &e));
    TEST_ASSERT_EQUAL_INT(HAL_ERR_RANGE, hal.sensors.adc_read(hal.sensors.ctx, NULL));

    hd_sim_nominal_t nom;
    hal_sim_nominal(&sim, &nom);
    TEST_ASSERT_DOUBLE_WITHIN(1e-5, 6.60, nom.gain_nm_per_v);
    TEST_ASSERT_DOUBLE_WITHIN(1e-15, 20.0 / 65536.0, nom.adc_v_per_count);
}

static void test_hal_adc_only_loop_steps_every_read(void)
{
    hd_sim_scenario_t sc;
    hd_sim_scenario_default(&sc);
    TEST_ASSERT_EQUAL_INT(0, hd_sim_scenario_parse(&sc, "duration_s = 0.005\nencoder_fault = 0.002:0.003\n",
                                                   "t", err, sizeof(err)));
    static hal_sim_t sim;
    TEST_ASSERT_EQUAL_INT(0, hal_sim_init(&sim, &sc, err, sizeof(err)));
    hal_t hal = {0};
    hal_sim_bind(&sim, &hal);
    hal_encoder_sample_t e;
    int faults = 0, k = 0;
    while (hal.sensors.encoder_read(hal.sensors.ctx, &e) == HAL_OK) {
        faults += e.fault;
        k++;
    }
    TEST_ASSERT_EQUAL_INT(5, k);
    TEST_ASSERT_EQUAL_INT(1, faults);
}

int main(int argc, char **argv)
{
    if (UnityParseOptions(argc, argv) != 0) {
        return 1;
    }
    UNITY_BEGIN();
    RUN_TEST(test_encoder_counts_follow_prescribed_angle);
    RUN_TEST(test_output_angle_is_motor_over_ratio);
    RUN_TEST(test_encoder_counts_wrap_below_zero);
    RUN_TEST(test_truth_is_rigid_body_plus_friction_plus_load_without_ripple);
    RUN_TEST(test_motor_ripple_line_amplitude_phase_and_frequency);
    RUN_TEST(test_output_and_fixed_lines);
    RUN_TEST(test_ripple_grows_with_load_when_enabled);
    RUN_TEST(test_offset_drift_is_linear_in_time);
    RUN_TEST(test_bridge_placement_error_gives_predicted_2x_line);
    RUN_TEST(test_adc_quantises_clips_and_flags_saturation);
    RUN_TEST(test_noise_std_matches);
    RUN_TEST(test_same_seed_same_run_other_seed_differs);
    RUN_TEST(test_parser_rejects_with_line_numbers);
    RUN_TEST(test_parser_accepts_comments_quotes_and_lists);
    RUN_TEST(test_parser_rejects_nul_with_its_line);
    RUN_TEST(test_missing_file_is_a_clear_error);
    RUN_TEST(test_hal_backend_ticks_and_ends);
    RUN_TEST(test_hal_adc_only_loop_steps_every_read);
    return UNITY_END();
}
