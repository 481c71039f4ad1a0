/*
 * hd_artifact (control/): the narrowband, angle-locked artifact estimate
 * against the closed forms of a first-order tracker per line (hd_artifact.h):
 * a line locked to the motor angle is removed fully; a step of its amplitude
 * leaves a residual that decays as exp(-2 pi fc t); a tone off the line by
 * d Hz passes with the notch's gain d / sqrt(d^2 + fc^2); a line learned
 * before a reversal is still removed after it.
 */
#include <math.h>
#include <stdio.h>

#include "hd_artifact.h"
#include "hd_ctrl_trig.h"
#include "unity.h"

#define TS 1e-3
#define PI_D 3.14159265358979323846
#define FC 0.5            /* corner Hz: tau = 1 / (2 pi fc) = 0.318 s */
#define MASK 0x0Au        /* orders 2 and 4 */
#define W_MOTOR 50.0      /* rad/s at the motor: the 2x line at 15.9 Hz */

void setUp(void) {}
void tearDown(void) {}

/* The gauge's artifact: a 2x and a 4x line of the motor angle. */
static double artifact(double theta, double a2)
{
    return a2 * sin(2.0 * theta + 1.1) + 0.3 * cos(4.0 * theta - 0.4);
}

/* Amplitude of x at f_hz over [i0, i0 + n) ticks (least squares, a whole
 * number of periods). */
static double amplitude(const double *x, long i0, long n, double f_hz)
{
    double c = 0.0, s = 0.0;
    for (long i = i0; i < i0 + n; i++) {
        const double ph = 2.0 * PI_D * f_hz * (double)i * TS;
        c += x[i] * cos(ph);
        s += x[i] * sin(ph);
    }
    return 2.0 * sqrt(c * c + s * s) / (double)n;
}

static double resid[20000];

/* The tick's sine and cosine against libm in double over [-pi, pi] (every
 * quadrant and both ends; 200001 points). */
static void test_sincos_quadrant_against_libm(void)
{
    double worst = 0.0;
    for (long i = -100000; i <= 100000; i++) {
        const float x = (float)(3.14159265358979 * (double)i / 100000.0);
        float s, c;
        sincos_quadrant(x, &s, &c);
        const double es = fabs((double)s - sin((double)x)), ec = fabs((double)c - cos((double)x));
        worst = es > worst ? es : worst;
        worst = ec > worst ? ec : worst;
    }
    printf("sincos_quadrant: worst error %.2e over [-pi, pi]\n", worst);
    TEST_ASSERT_TRUE(worst < 3e-7);
}

/* A steady line is removed fully; after an amplitude step at t0 the
 * residual's amplitude is the step times exp(-(t - t0) / tau). */
static void test_steady_line_removed_and_step_after_tau(void)
{
    hd_artifact_t t;
    hd_artifact_init(&t, MASK, (float)FC, (float)TS);
    const long n = 20000, i0 = 8000;     /* the step at 8 s */
    const double f2 = 2.0 * W_MOTOR / (2.0 * PI_D), da = 1.0;
    for (long i = 0; i < n; i++) {
        const double theta = W_MOTOR * (double)i * TS;
        const double a = artifact(theta, i < i0 ? 1.5 : 1.5 + da);
        /* the firmware's angle: wrapped to [0, 2 pi) */
        const float th = (float)fmod(theta, 2.0 * PI_D);
        const double est = (double)hd_artifact_step(&t, (float)a, th, 1.0f);
        resid[i] = a - est;
    }
    double worst = 0.0;
    for (long i = i0 - 500; i < i0; i++) {
        worst = fmax(worst, fabs(resid[i]));
    }
    TEST_ASSERT_TRUE_MESSAGE(worst < 2e-3, "a steady line is removed fully");
    /* the residual's 2x amplitude over one period of the line (63 ticks)
     * centred on t0 + x tau */
    const double tau = 1.0 / (2.0 * PI_D * FC);
    const long per = (long)lround(1.0 / (f2 * TS));
    const double xs[] = {0.1, 1.0, 2.0}; /* 0.1 tau: the window after the step */
    for (unsigned j = 0; j < 3u; j++) {
        const long c = i0 + (long)lround(xs[j] * tau / TS);
        const double got = amplitude(resid, c - per / 2, per, f2);
        const double want = da * exp(-xs[j]);
        TEST_ASSERT_DOUBLE_WITHIN_MESSAGE(0.1 * want + 0.01, want, got,
                                          "the step decays as exp(-t / tau)");
    }
}

/* A new mask keeps what both masks share: with order 4 dropped the learned
 * 2x line is still removed at once; order 4 taken back starts at 0, so the
 * residual right after is the whole 4x line (0.3 N m). */
static void test_remask_keeps_the_common_orders(void)
{
    hd_artifact_t t;
    hd_artifact_init(&t, MASK, (float)FC, (float)TS);
    long i = 0;
    for (; i < 8000; i++) {
        const double theta = W_MOTOR * (double)i * TS;
        (void)hd_artifact_step(&t, (float)artifact(theta, 1.5), (float)fmod(theta, 2.0 * PI_D), 1.0f);
    }
    hd_artifact_remask(&t, 0x02u);
    TEST_ASSERT_EQUAL_FLOAT(0.0f, t.re[4]);
    TEST_ASSERT_EQUAL_FLOAT(0.0f, t.im[4]);
    double worst = 0.0;
    const long per4 = (long)lround(2.0 * PI_D / (4.0 * W_MOTOR * TS)); /* 31 ticks */
    for (long j = 0; j < 4 * per4; j++, i++) {
        const double theta = W_MOTOR * (double)i * TS;
        const double a = 1.5 * sin(2.0 * theta + 1.1); /* the 2x line alone */
        worst = fmax(worst, fabs(a - (double)hd_artifact_step(&t, (float)a,
                                                              (float)fmod(theta, 2.0 * PI_D), 1.0f)));
    }
    printf("remask: 2x kept, worst residual %.2e N m\n", worst);
    TEST_ASSERT_TRUE_MESSAGE(worst < 2e-3, "the kept order's phasor holds");
    hd_artifact_remask(&t, MASK);
    for (long j = 0; j < per4; j++, i++) {
        const double theta = W_MOTOR * (double)i * TS;
        const double a = artifact(theta, 1.5);
        resid[j] = a - (double)hd_artifact_step(&t, (float)a, (float)fmod(theta, 2.0 * PI_D), 0.0f);
    }
    double peak = 0.0;
    for (long j = 0; j < per4; j++) {
        peak = fmax(peak, fabs(resid[j]));
    }
    TEST_ASSERT_DOUBLE_WITHIN_MESSAGE(0.02, 0.3, peak, "the order that enters starts at 0");
}

/* A tone at the 2x line's frequency plus d Hz, not locked to the angle,
 * passes with |H| = d / sqrt(d^2 + fc^2) (steady state); with the line too. */
static void test_unlocked_tone_passes_with_the_notch_gain(void)
{
    const double ds[] = {0.5, 2.0, -3.0};
    const double f2 = 2.0 * W_MOTOR / (2.0 * PI_D);
    for (unsigned j = 0; j < 3u; j++) {
        hd_artifact_t t;
        hd_artifact_init(&t, MASK, (float)FC, (float)TS);
        const double f = f2 + ds[j];
        const long n = 16000;
        for (long i = 0; i < n; i++) {
            const double time = (double)i * TS, theta = W_MOTOR * time;
            const double tone = 0.8 * sin(2.0 * PI_D * f * time + 0.3);
            const double a = artifact(theta, 1.5) + tone;
            resid[i] = a - (double)hd_artifact_step(&t, (float)a, (float)fmod(theta, 2.0 * PI_D), 1.0f);
        }
        /* the tone's amplitude in the residual over the last 4 s (the line
         * removed; 4 s holds whole periods of the beat within 1 %) */
        const double got = amplitude(resid, n - 4000, 4000, f) / 0.8;
        const double want = fabs(ds[j]) / sqrt(ds[j] * ds[j] + FC * FC);
        TEST_ASSERT_DOUBLE_WITHIN_MESSAGE(0.03, want, got, "the notch's gain off the line");
    }
}

/* Locked to the angle, not to the speed: learned turning one way, the line
 * is removed at once after the motor reverses; with m = 0 nothing is
 * learned. */
static void test_reversal_and_hold(void)
{
    hd_artifact_t t;
    hd_artifact_init(&t, MASK, (float)FC, (float)TS);
    double theta = 0.0, worst = 0.0;
    for (long i = 0; i < 12000; i++) {
        const double w = i < 6000 ? W_MOTOR : -W_MOTOR;
        theta += w * TS;
        const double a = artifact(theta, 1.5);
        const double r = a - (double)hd_artifact_step(&t, (float)a, (float)theta, 1.0f);
        if (i >= 6000 && i < 6200) {
            worst = fmax(worst, fabs(r));
        }
    }
    TEST_ASSERT_TRUE_MESSAGE(worst < 5e-3, "removed right after the reversal");
    hd_artifact_t z;
    hd_artifact_init(&z, MASK, (float)FC, (float)TS);
    for (long i = 0; i < 1000; i++) {
        (void)hd_artifact_step(&z, 1.0f, (float)(W_MOTOR * (double)i * TS), 0.0f);
    }
    TEST_ASSERT_EQUAL_FLOAT(0.0f, hd_artifact_step(&z, 1.0f, 0.3f, 0.0f));
}

int main(void)
{
    UNITY_BEGIN();
    RUN_TEST(test_sincos_quadrant_against_libm);
    RUN_TEST(test_steady_line_removed_and_step_after_tau);
    RUN_TEST(test_remask_keeps_the_common_orders);
    RUN_TEST(test_unlocked_tone_passes_with_the_notch_gain);
    RUN_TEST(test_reversal_and_hold);
    return UNITY_END();
}
