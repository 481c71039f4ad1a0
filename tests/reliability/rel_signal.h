/*
 * rel_signal: an independent double-precision joint signal for the soak and
 * the filter bad-input tests (header-only, host test code).
 *
 *   motor speed  w(t): a 20 s periodic profile (see rel_speed) covering
 *                standstill, slow and fast motion, both directions;
 *   truth        T(t) = 3 + 2 sin(2 pi t / 20 s) N m (slow load);
 *   ripple       1.0 sin(2 th + 0.3) + 0.4 sin(4 th + 1.1)  (motor orders)
 *                + 0.5 sin(th / N - 0.7)                     (misalignment)
 *   measurement  T + ripple + N(0, noise^2);
 *   encoder      4096 counts per motor rev, increments as the firmware
 *                computes them (count delta x 2 pi / 4096, float).
 */
#ifndef REL_SIGNAL_H
#define REL_SIGNAL_H

#include <math.h>
#include <stdint.h>

#define REL_PI 3.14159265358979323846
#define REL_TS_S 0.001
#define REL_GEAR 100.0
#define REL_CPR 4096.0
#define REL_PERIOD_S 20.0

typedef struct {
    uint64_t k;
    double theta_rad; /* motor angle */
    int64_t counts;
    uint64_t rng;
    double noise_nm;
    /* this step */
    double truth_nm;
    double meas_nm;
    float d_motor_rad;
    float d_output_rad;
    double speed_rad_s;
} rel_signal_t;

/* Piecewise linear over one 20 s period (rad/s): 0 (standstill) -> 156 ->
 * 300 -> 156 -> -156 (reversal) -> 20 (slow) -> 0. */
static inline double rel_speed(double t_s)
{
    static const double tp[] = {0.0, 1.0, 3.0, 6.0, 9.0, 11.0, 14.0, 15.0, 18.0, 19.0, 20.0};
    static const double wp[] = {0.0, 0.0, 156.0, 300.0, 156.0, 156.0, -156.0, -156.0, 20.0, 0.0, 0.0};
    double u = fmod(t_s, REL_PERIOD_S);
    for (int i = 0; i < 10; i++) {
        if (u < tp[i + 1]) {
            double a = (u - tp[i]) / (tp[i + 1] - tp[i]);
            return wp[i] + a * (wp[i + 1] - wp[i]);
        }
    }
    return 0.0;
}

static inline double rel_uniform(rel_signal_t *s)
{
    /* xorshift64*: deterministic, good enough for test noise */
    s->rng ^= s->rng >> 12;
    s->rng ^= s->rng << 25;
    s->rng ^= s->rng >> 27;
    return (double)((s->rng * 2685821657736338717ull) >> 11) * (1.0 / 9007199254740992.0);
}

static inline double rel_gauss(rel_signal_t *s)
{
    double u1 = rel_uniform(s);
    double u2 = rel_uniform(s);
    if (u1 < 1e-300) {
        u1 = 1e-300;
    }
    return sqrt(-2.0 * log(u1)) * cos(2.0 * REL_PI * u2);
}

static inline void rel_signal_init(rel_signal_t *s, uint64_t seed, double noise_nm)
{
    s->k = 0;
    s->theta_rad = 0.0;
    s->counts = 0;
    s->rng = seed * 0x9E3779B97F4A7C15ull + 1ull;
    s->noise_nm = noise_nm;
}

/* Advances one sample. */
static inline void rel_signal_step(rel_signal_t *s)
{
    double t = (double)s->k * REL_TS_S;
    /* trapezoidal integration of the speed (exact for piecewise linear
     * within a step except at breakpoints) */
    double w0 = rel_speed(t);
    double w1 = rel_speed(t + REL_TS_S);
    s->theta_rad += 0.5 * (w0 + w1) * REL_TS_S;
    s->speed_rad_s = w1;
    int64_t c = (int64_t)floor(s->theta_rad * REL_CPR / (2.0 * REL_PI));
    int64_t dc = c - s->counts;
    s->counts = c;
    s->d_motor_rad = (float)dc * (float)(2.0 * REL_PI / REL_CPR);
    s->d_output_rad = s->d_motor_rad / (float)REL_GEAR;
    double tt = t + REL_TS_S;
    s->truth_nm = 3.0 + 2.0 * sin(2.0 * REL_PI * tt / REL_PERIOD_S);
    double th = s->theta_rad;
    double ripple = 1.0 * sin(2.0 * th + 0.3) + 0.4 * sin(4.0 * th + 1.1) +
                    0.5 * sin(th / REL_GEAR - 0.7);
    s->meas_nm = s->truth_nm + ripple + s->noise_nm * rel_gauss(s);
    s->k++;
}

#endif /* REL_SIGNAL_H */
