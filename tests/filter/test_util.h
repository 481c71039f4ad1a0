/*
 * Small double-precision helpers shared by the filter tests (test-only code):
 * a deterministic Gaussian noise source, a piecewise-linear motor speed
 * profile integrated to angle, and a least-squares line-amplitude estimator.
 * Everything here is independent of the code under test.
 */
#ifndef HD_TEST_UTIL_H
#define HD_TEST_UTIL_H

#include <math.h>
#include <stddef.h>
#include <stdint.h>

#define TU_PI 3.14159265358979323846

/* ---- deterministic noise (splitmix64 + Box-Muller) --------------------- */
typedef struct {
    uint64_t s;
    int has_spare;
    double spare;
} tu_rng_t;

static inline void tu_rng_seed(tu_rng_t *r, uint64_t seed)
{
    r->s = seed;
    r->has_spare = 0;
    r->spare = 0.0;
}

static inline double tu_uniform(tu_rng_t *r) /* in (0, 1) */
{
    uint64_t z = (r->s += 0x9E3779B97F4A7C15ull);
    z = (z ^ (z >> 30)) * 0xBF58476D1CE4E5B9ull;
    z = (z ^ (z >> 27)) * 0x94D049BB133111EBull;
    z ^= z >> 31;
    return ((double)(z >> 11) + 0.5) * (1.0 / 9007199254740992.0);
}

static inline double tu_gauss(tu_rng_t *r) /* zero mean, unit variance */
{
    if (r->has_spare) {
        r->has_spare = 0;
        return r->spare;
    }
    double u1 = tu_uniform(r), u2 = tu_uniform(r);
    double mag = sqrt(-2.0 * log(u1));
    r->spare = mag * sin(2.0 * TU_PI * u2);
    r->has_spare = 1;
    return mag * cos(2.0 * TU_PI * u2);
}

/* ---- speed profile: piecewise linear speed knots (t [s], omega [rad/s]) - */
typedef struct {
    const double *t_s;
    const double *omega_rad_s;
    size_t knots;
} tu_profile_t;

static inline double tu_profile_omega(const tu_profile_t *p, double t_s)
{
    if (t_s <= p->t_s[0])
        return p->omega_rad_s[0];
    for (size_t i = 1; i < p->knots; i++) {
        if (t_s <= p->t_s[i]) {
            double a = (t_s - p->t_s[i - 1]) / (p->t_s[i] - p->t_s[i - 1]);
            return p->omega_rad_s[i - 1] + a * (p->omega_rad_s[i] - p->omega_rad_s[i - 1]);
        }
    }
    return p->omega_rad_s[p->knots - 1];
}

/* Motor angle integrator: trapezoid rule, exact for piecewise-linear speed
 * when knots fall on samples.  Increments are causal: the increment passed
 * with sample k is angle(k) - angle(k-1), as an encoder delivers it. */
typedef struct {
    const tu_profile_t *prof;
    double ts_s;
    long k;
    double angle_rad;     /* motor angle at sample k */
    double omega_rad_s;   /* motor speed at sample k */
    double d_angle_rad;   /* angle(k) - angle(k-1) */
} tu_motion_t;

static inline void tu_motion_init(tu_motion_t *m, const tu_profile_t *prof, double ts_s)
{
    m->prof = prof;
    m->ts_s = ts_s;
    m->k = 0;
    m->angle_rad = 0.0;
    m->omega_rad_s = tu_profile_omega(prof, 0.0);
    m->d_angle_rad = 0.0;
}

/* Advances to the next sample. */
static inline void tu_motion_next(tu_motion_t *m)
{
    double w0 = m->omega_rad_s;
    m->k++;
    m->omega_rad_s = tu_profile_omega(m->prof, (double)m->k * m->ts_s);
    m->d_angle_rad = 0.5 * (w0 + m->omega_rad_s) * m->ts_s;
    m->angle_rad += m->d_angle_rad;
}

/* ---- line amplitude by least squares ------------------------------------
 * Fits sig[k] ~ a cos(phase[k]) + b sin(phase[k]) + c and returns
 * sqrt(a^2 + b^2).  phase[] is the known line phase (order * angle), so this
 * works at any speed profile, not only at constant speed. */
static inline double tu_line_amplitude(const double *sig, const double *phase, size_t n)
{
    double m[3][4] = {{0}};
    for (size_t k = 0; k < n; k++) {
        double r[3] = {cos(phase[k]), sin(phase[k]), 1.0};
        for (int i = 0; i < 3; i++) {
            for (int j = 0; j < 3; j++)
                m[i][j] += r[i] * r[j];
            m[i][3] += r[i] * sig[k];
        }
    }
    /* Gauss-Jordan with partial pivoting on the 3x4 augmented system. */
    for (int c = 0; c < 3; c++) {
        int piv = c;
        for (int i = c + 1; i < 3; i++)
            if (fabs(m[i][c]) > fabs(m[piv][c]))
                piv = i;
        for (int j = 0; j < 4; j++) {
            double tmp = m[c][j];
            m[c][j] = m[piv][j];
            m[piv][j] = tmp;
        }
        if (m[c][c] == 0.0)
            return NAN;
        for (int i = 0; i < 3; i++) {
            if (i == c)
                continue;
            double f = m[i][c] / m[c][c];
            for (int j = c; j < 4; j++)
                m[i][j] -= f * m[c][j];
        }
    }
    double a = m[0][3] / m[0][0], b = m[1][3] / m[1][1];
    return sqrt(a * a + b * b);
}

static inline double tu_rms(const double *v, size_t n)
{
    double s = 0.0;
    for (size_t k = 0; k < n; k++)
        s += v[k] * v[k];
    return n ? sqrt(s / (double)n) : 0.0;
}

static inline double tu_db(double ratio) { return 20.0 * log10(ratio); }

#endif /* HD_TEST_UTIL_H */
