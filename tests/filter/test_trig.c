/*
 * hd_sincosf against libm double sin/cos of the same float input, over a
 * dense sweep, with the bounds stated in hd_trig.h:
 *   max abs error < 2e-7 on [-pi, pi], < 1e-6 for |angle| up to 1e4 rad,
 *   non-finite or |angle| > 1e5 rad -> sin 0, cos 1.
 */
#include <float.h>
#include <math.h>
#include <stdio.h>

#include "hd_trig.h"
#include "unity.h"
#include "../reliability/rel_measured.h"

#define TU_PI_D 3.14159265358979323846

void setUp(void) {}
void tearDown(void) {}

typedef struct {
    double max_sin, max_cos;
    double at_sin, at_cos;
} err_t_;

static void sweep(double lo, double hi, long n, err_t_ *e)
{
    e->max_sin = e->max_cos = 0.0;
    e->at_sin = e->at_cos = 0.0;
    for (long i = 0; i <= n; i++) {
        float a = (float)(lo + (hi - lo) * (double)i / (double)n);
        float s, c;
        hd_sincosf(a, &s, &c);
        double es = fabs((double)s - sin((double)a)), ec = fabs((double)c - cos((double)a));
        if (es > e->max_sin) {
            e->max_sin = es;
            e->at_sin = (double)a;
        }
        if (ec > e->max_cos) {
            e->max_cos = ec;
            e->at_cos = (double)a;
        }
    }
}

static void report(const char *key, const char *range, const err_t_ *e, double bound)
{
    rel_measured(key, "sin=%.2g cos=%.2g bound=%g", e->max_sin, e->max_cos, bound);
    char m[200];
    snprintf(m, sizeof(m), "%s: max |sin err| %.3g (at %.6g), max |cos err| %.3g (at %.6g)", range,
             e->max_sin, e->at_sin, e->max_cos, e->at_cos);
    TEST_MESSAGE(m);
}

static void test_sincos_within_2e7_on_minus_pi_pi(void)
{
    err_t_ e;
    sweep(-TU_PI_D, TU_PI_D, 2000000L, &e);
    const double bound = 2e-7;
    report("trig_pi", "[-pi, pi], 2e6 points", &e, bound);
    TEST_ASSERT_LESS_THAN_DOUBLE(bound, e.max_sin);
    TEST_ASSERT_LESS_THAN_DOUBLE(bound, e.max_cos);
}

/* Every float in a neighbourhood of the quadrant boundaries (where range
 * reduction switches polynomials) and of 0 and +-pi. */
static void test_sincos_quadrant_boundaries_exhaustive(void)
{
    static const double centres[] = {0.0, 0.785398163397448, -0.785398163397448,
                                      2.356194490192345, -2.356194490192345,
                                      1.570796326794897, -1.570796326794897,
                                      3.141592653589793, -3.141592653589793};
    double worst = 0.0;
    for (unsigned c = 0; c < sizeof(centres) / sizeof(centres[0]); c++) {
        float a = (float)centres[c];
        for (int i = 0; i < 20000; i++)
            a = nextafterf(a, -INFINITY);
        for (int i = 0; i < 40000; i++) {
            float s, co;
            hd_sincosf(a, &s, &co);
            double e = fmax(fabs((double)s - sin((double)a)), fabs((double)co - cos((double)a)));
            if (fabs((double)a) <= TU_PI_D && e > worst)
                worst = e;
            a = nextafterf(a, INFINITY);
        }
    }
    char m[100];
    snprintf(m, sizeof(m), "quadrant boundaries, 40000 consecutive floats each: max err %.3g", worst);
    TEST_MESSAGE(m);
    const double bound = 2e-7;
    rel_measured("trig_boundaries", "err=%.2g bound=%g", worst, bound);
    TEST_ASSERT_LESS_THAN_DOUBLE(bound, worst);
}

static void test_sincos_within_1e6_up_to_1e4_rad(void)
{
    err_t_ e;
    sweep(-1e4, 1e4, 4000000L, &e);
    const double bound = 1e-6;
    report("trig_1e4", "[-1e4, 1e4] rad, 4e6 points", &e, bound);
    TEST_ASSERT_LESS_THAN_DOUBLE(bound, e.max_sin);
    TEST_ASSERT_LESS_THAN_DOUBLE(bound, e.max_cos);
    /* the largest floats in range, where reduction error is worst */
    double worst = 0.0;
    float a = 1e4f;
    for (int i = 0; i < 100000; i++) {
        float s, c;
        hd_sincosf(a, &s, &c);
        worst = fmax(worst, fmax(fabs((double)s - sin((double)a)), fabs((double)c - cos((double)a))));
        float na = -a;
        hd_sincosf(na, &s, &c);
        worst = fmax(worst, fmax(fabs((double)s - sin((double)na)), fabs((double)c - cos((double)na))));
        a = nextafterf(a, 0.0f);
    }
    char m[100];
    snprintf(m, sizeof(m), "100000 floats just below 1e4 rad: max err %.3g", worst);
    TEST_MESSAGE(m);
    rel_measured("trig_near_1e4", "err=%.2g bound=%g", worst, bound);
    TEST_ASSERT_LESS_THAN_DOUBLE(bound, worst);
}

static void test_sincos_exact_points_and_identity(void)
{
    float s, c;
    hd_sincosf(0.0f, &s, &c);
    TEST_ASSERT_EQUAL_FLOAT(0.0f, s);
    TEST_ASSERT_EQUAL_FLOAT(1.0f, c);
    /* odd / even symmetry and sin^2 + cos^2 = 1 within float rounding */
    double worst_sym = 0.0, worst_id = 0.0;
    for (int i = 1; i < 100000; i++) {
        float a = (float)(i * 1e-4 * 3.7);
        float s1, c1, s2, c2;
        hd_sincosf(a, &s1, &c1);
        hd_sincosf(-a, &s2, &c2);
        worst_sym = fmax(worst_sym, fmax(fabs((double)s1 + (double)s2), fabs((double)c1 - (double)c2)));
        worst_id = fmax(worst_id, fabs((double)s1 * (double)s1 + (double)c1 * (double)c1 - 1.0));
    }
    TEST_ASSERT_LESS_THAN_DOUBLE(4e-7, worst_sym);
    TEST_ASSERT_LESS_THAN_DOUBLE(1e-6, worst_id);
}

static void test_sincos_nonfinite_and_huge(void)
{
    static const float bad[] = {NAN, INFINITY, -INFINITY, 2e5f, -1e6f, FLT_MAX};
    for (unsigned i = 0; i < sizeof(bad) / sizeof(bad[0]); i++) {
        float s = 123.0f, c = 123.0f;
        hd_sincosf(bad[i], &s, &c);
        TEST_ASSERT_EQUAL_FLOAT(0.0f, s);
        TEST_ASSERT_EQUAL_FLOAT(1.0f, c);
    }
}

int main(int argc, char **argv)
{
    if (UnityParseOptions(argc, argv) != 0) {
        return 1;
    }
    UNITY_BEGIN();
    RUN_TEST(test_sincos_within_2e7_on_minus_pi_pi);
    RUN_TEST(test_sincos_quadrant_boundaries_exhaustive);
    RUN_TEST(test_sincos_within_1e6_up_to_1e4_rad);
    RUN_TEST(test_sincos_exact_points_and_identity);
    RUN_TEST(test_sincos_nonfinite_and_huge);
    return UNITY_END();
}
