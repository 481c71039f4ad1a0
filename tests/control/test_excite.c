/*
 * hd_excite (control/): the identification's multisine against its closed
 * form in double, x(t) = rms sqrt(2 / n) sum_k cos(2 pi b_k t / P - pi k (k + 1) / n),
 * to the table's quantization; its rms and peak; the bins; bad arguments.
 */
#include <math.h>
#include <stdio.h>
#include <string.h>

#include "hd_excite.h"
#include "unity.h"

#define PI_D 3.14159265358979323846
#define P HD_EXCITE_PERIOD_TICKS
#define N HD_EXCITE_LINES

void setUp(void) {}
void tearDown(void) {}

static hd_excite_t g_e; /* 4 KB: not on the test's stack */

static double closed_form(uint32_t t, double rms)
{
    double x = 0.0;
    for (uint32_t k = 0; k < N; k++) {
        x += cos(2.0 * PI_D * hd_excite_bins[k] * (double)t / P - PI_D * k * (k + 1.0) / N);
    }
    return x * rms * sqrt(2.0 / N);
}

static void test_bins_are_log_spaced_from_1_to_450_hz(void)
{
    const double df_hz = 1.0 / (P * 1e-3);
    TEST_ASSERT_EQUAL_DOUBLE(1.0, hd_excite_bins[0] * df_hz);
    TEST_ASSERT_EQUAL_DOUBLE(450.0, hd_excite_bins[N - 1] * df_hz);
    for (uint32_t k = 1; k < N; k++) {
        TEST_ASSERT_TRUE(hd_excite_bins[k] > hd_excite_bins[k - 1]);
        /* log spacing: no step beyond the geometric ratio 450^(1/47) rounded up a bin */
        TEST_ASSERT_TRUE(hd_excite_bins[k] <= hd_excite_bins[k - 1] * pow(450.0, 1.0 / 47.0) + 1.0);
        TEST_ASSERT_TRUE(hd_excite_bins[k] >= hd_excite_bins[k - 1] * pow(450.0, 1.0 / 47.0) - 1.0);
    }
}

static void test_waveform_is_the_closed_form_to_its_quantization(void)
{
    const float rms = 0.4f;
    TEST_ASSERT_EQUAL_INT(HD_CTRL_OK, hd_excite_build(&g_e, rms));
    double worst = 0.0, sum_sq = 0.0, peak = 0.0;
    for (uint32_t t = 0; t < P; t++) {
        const double want = closed_form(t, rms);
        const double got = (double)hd_excite_at(&g_e, t);
        worst = fmax(worst, fabs(got - want));
        sum_sq += got * got;
        peak = fmax(peak, fabs(want));
    }
    const double count = (double)g_e.a_per_count, peak_a = (double)g_e.peak_a;
    printf("excite: rms %.4f A, peak %.4f A (crest %.2f), worst error %.2e A (%.2f counts)\n",
           sqrt(sum_sq / P), peak_a, peak_a / (double)rms, worst, worst / count);
    /* half a count of rounding plus float32's sines summed over 43 lines */
    TEST_ASSERT_TRUE(worst < 0.5 * count + 2e-6 * peak_a * N);
    TEST_ASSERT_DOUBLE_WITHIN(1e-4 * (double)rms, (double)rms, sqrt(sum_sq / P));
    TEST_ASSERT_DOUBLE_WITHIN(1e-5 * peak, peak, peak_a);
    TEST_ASSERT_EQUAL_FLOAT(rms, g_e.rms_a);
}

static void test_periodic_and_scaled(void)
{
    TEST_ASSERT_EQUAL_INT(HD_CTRL_OK, hd_excite_build(&g_e, 2.0f));
    const float a = hd_excite_at(&g_e, 123u);
    TEST_ASSERT_EQUAL_FLOAT(a, hd_excite_at(&g_e, 123u + 7u * P));
    TEST_ASSERT_DOUBLE_WITHIN(2.0 * (double)g_e.a_per_count, closed_form(123u, 2.0), (double)a);
}

static void test_bad_rms_is_refused_and_changes_nothing(void)
{
    TEST_ASSERT_EQUAL_INT(HD_CTRL_OK, hd_excite_build(&g_e, 1.0f));
    hd_excite_t before;
    memcpy(&before, &g_e, sizeof before);
    const float bad[] = {0.0f, HD_EXCITE_RMS_MIN_A * 0.99f, -1.0f, NAN, INFINITY, HD_EXCITE_RMS_MAX_A * 1.01f};
    for (unsigned i = 0; i < sizeof bad / sizeof bad[0]; i++) {
        TEST_ASSERT_EQUAL_INT(HD_CTRL_ERR_CONFIG, hd_excite_build(&g_e, bad[i]));
        TEST_ASSERT_EQUAL_MEMORY(&before, &g_e, sizeof before);
    }
    TEST_ASSERT_EQUAL_INT(HD_CTRL_ERR_NULL, hd_excite_build(NULL, 1.0f));
}

int main(void)
{
    UNITY_BEGIN();
    RUN_TEST(test_bins_are_log_spaced_from_1_to_450_hz);
    RUN_TEST(test_waveform_is_the_closed_form_to_its_quantization);
    RUN_TEST(test_periodic_and_scaled);
    RUN_TEST(test_bad_rms_is_refused_and_changes_nothing);
    return UNITY_END();
}
