/* hd_calib_lsq: see hd_calib_lsq.h. */
#include "hd_calib_lsq.h"

#include <math.h>
#include <string.h>

static float dot(const float *a, const float *b, uint32_t n)
{
    float s = 0.0f;
    for (uint32_t i = 0; i < n; ++i) {
        s += a[i] * b[i];
    }
    return s;
}

void hd_calib_lsq_solve(const design_t *d, const float *y, lsq_t *out)
{
    static const float drop_ratio = 1e-4f;
    float q[LSQ_MAX_COLS][HD_CALIB_MAX_POINTS];
    float r[LSQ_MAX_COLS][LSQ_MAX_COLS];
    float z[HD_CALIB_MAX_POINTS];
    float c[LSQ_MAX_COLS] = {0.0f};
    uint32_t idx[LSQ_MAX_COLS] = {0u};
    uint32_t k = 0;
    const uint32_t n = d->n;

    memset(out, 0, sizeof *out);
    memset(r, 0, sizeof r);
    for (uint32_t j = 0; j < d->p; ++j) {
        float *v = q[k];
        memcpy(v, d->x[j], n * sizeof(float));
        float norm0 = sqrtf(dot(v, v, n));
        for (uint32_t m = 0; m < k; ++m) {
            float rm = dot(q[m], v, n);
            r[m][k] = rm;
            for (uint32_t i = 0; i < n; ++i) {
                v[i] -= rm * q[m][i];
            }
        }
        float norm = sqrtf(dot(v, v, n));
        out->se[j] = NAN;
        if (norm0 <= 0.0f || norm <= drop_ratio * norm0) {
            continue;
        }
        r[k][k] = norm;
        for (uint32_t i = 0; i < n; ++i) {
            v[i] /= norm;
        }
        idx[k] = j;
        out->used[j] = 1u;
        ++k;
    }
    out->rank = k;
    memcpy(z, y, n * sizeof(float));
    for (uint32_t m = 0; m < k; ++m) {
        c[m] = dot(q[m], z, n);
        for (uint32_t i = 0; i < n; ++i) {
            z[i] -= c[m] * q[m][i];
        }
    }
    out->rss = dot(z, z, n);
    /* Back substitution R b = c. */
    float b[LSQ_MAX_COLS] = {0.0f};
    for (uint32_t mm = k; mm-- > 0;) {
        float s = c[mm];
        for (uint32_t l = mm + 1u; l < k; ++l) {
            s -= r[mm][l] * b[l];
        }
        b[mm] = s / r[mm][mm];
    }
    /* Rinv (upper triangular); cov = sigma^2 Rinv Rinv^T. */
    float ri[LSQ_MAX_COLS][LSQ_MAX_COLS];
    memset(ri, 0, sizeof ri);
    for (uint32_t col = 0; col < k; ++col) {
        for (uint32_t mm = col + 1u; mm-- > 0;) {
            float s = (mm == col) ? 1.0f : 0.0f;
            for (uint32_t l = mm + 1u; l <= col; ++l) {
                s -= r[mm][l] * ri[l][col];
            }
            ri[mm][col] = s / r[mm][mm];
        }
    }
    float sigma2 = (n > k) ? out->rss / (float)(n - k) : NAN;
    for (uint32_t m = 0; m < k; ++m) {
        float var = 0.0f;
        for (uint32_t l = m; l < k; ++l) {
            var += ri[m][l] * ri[m][l];
        }
        out->beta[idx[m]] = b[m];
        out->se[idx[m]] = sqrtf(var * sigma2);
    }
}

/* ln Gamma(x), x > 0: Lanczos (g = 7, n = 9), plenty for float p-values. */
static float lgamma_pos(float x)
{
    static const float coef[9] = {
        0.99999999999980993f, 676.5203681218851f, -1259.1392167224028f,
        771.32342877765313f, -176.61502916214059f, 12.507343278686905f,
        -0.13857109526572012f, 9.9843695780195716e-6f, 1.5056327351493116e-7f};
    if (x < 0.5f) {
        /* Reflection: Gamma(x) Gamma(1-x) = pi / sin(pi x). */
        return logf(PI_F / sinf(PI_F * x)) - lgamma_pos(1.0f - x);
    }
    x -= 1.0f;
    float a = coef[0];
    float t = x + 7.5f;
    for (unsigned i = 1; i < 9u; ++i) {
        a += coef[i] / (x + (float)i);
    }
    return 0.91893853f + (x + 0.5f) * logf(t) - t + logf(a);
}

/* Continued fraction for the incomplete beta (modified Lentz). */
static float beta_cf(float a, float b, float x)
{
    const float tiny = 1e-30f;
    float qab = a + b, qap = a + 1.0f, qam = a - 1.0f;
    float c = 1.0f, d = 1.0f - qab * x / qap;
    if (abs_f(d) < tiny) {
        d = tiny;
    }
    d = 1.0f / d;
    float h = d;
    for (unsigned m = 1; m <= 200u; ++m) {
        float fm = (float)m, m2 = 2.0f * fm;
        float aa = fm * (b - fm) * x / ((qam + m2) * (a + m2));
        d = 1.0f + aa * d;
        d = abs_f(d) < tiny ? tiny : d;
        c = 1.0f + aa / c;
        c = abs_f(c) < tiny ? tiny : c;
        d = 1.0f / d;
        h *= d * c;
        aa = -(a + fm) * (qab + fm) * x / ((a + m2) * (qap + m2));
        d = 1.0f + aa * d;
        d = abs_f(d) < tiny ? tiny : d;
        c = 1.0f + aa / c;
        c = abs_f(c) < tiny ? tiny : c;
        d = 1.0f / d;
        float del = d * c;
        h *= del;
        if (abs_f(del - 1.0f) < 1e-7f) {
            break;
        }
    }
    return h;
}

/* Regularized incomplete beta I_x(a, b). */
static float beta_inc(float a, float b, float x)
{
    if (x <= 0.0f) {
        return 0.0f;
    }
    if (x >= 1.0f) {
        return 1.0f;
    }
    float lbt = lgamma_pos(a + b) - lgamma_pos(a) - lgamma_pos(b) + a * logf(x) +
                b * logf(1.0f - x);
    float bt = expf(lbt);
    if (x < (a + 1.0f) / (a + b + 2.0f)) {
        return bt * beta_cf(a, b, x) / a;
    }
    return 1.0f - bt * beta_cf(b, a, 1.0f - x) / b;
}

float hd_calib_f_pvalue(float f, float q, float df)
{
    if (!(q > 0.0f) || !(df > 0.0f) || f != f) {
        return NAN;
    }
    if (f <= 0.0f) {
        return 1.0f;
    }
    if (!finite_f(f)) {
        return 0.0f;
    }
    return beta_inc(0.5f * df, 0.5f * q, df / (df + q * f));
}

float hd_calib_nested_pvalue(const lsq_t *reduced, const lsq_t *full, uint32_t n)
{
    uint32_t q = full->rank - reduced->rank;
    if (q == 0u || n <= full->rank) {
        return NAN;
    }
    float df = (float)(n - full->rank);
    float num = (reduced->rss - full->rss) / (float)q;
    if (num < 0.0f) {
        num = 0.0f; /* rounding */
    }
    float den = full->rss / df;
    if (den <= 0.0f) {
        return num > 0.0f ? 0.0f : 1.0f;
    }
    return hd_calib_f_pvalue(num / den, (float)q, df);
}
