/* dense_kf_f32: see dense_kf_f32.h. */
#include "dense_kf_f32.h"

#include <string.h>

#include "hd_trig.h"

int dense_kf_init(dense_kf_t *kf, unsigned blocks, const float *orders, int offset,
                  float q, float r, float p0)
{
    unsigned n = 2u * blocks + (offset ? 1u : 0u);
    if (blocks > DENSE_KF_MAX_BLOCKS || n == 0u || n > DENSE_KF_MAX_STATES) {
        return -1;
    }
    memset(kf, 0, sizeof *kf);
    kf->n = n;
    kf->blocks = blocks;
    for (unsigned b = 0; b < blocks; b++) {
        kf->order[b] = orders[b];
        kf->c[2u * b] = 1.0f;
    }
    if (offset) {
        kf->c[n - 1u] = 1.0f;
    }
    for (unsigned i = 0; i < n; i++) {
        kf->p[i][i] = p0;
        kf->q[i][i] = q;
    }
    kf->r = r;
    return 0;
}

static void build_phi(dense_kf_t *kf, float d_angle_rad)
{
    unsigned n = kf->n;
    for (unsigned i = 0; i < n; i++) {
        for (unsigned j = 0; j < n; j++) {
            kf->phi[i][j] = 0.0f;
        }
    }
    for (unsigned b = 0; b < kf->blocks; b++) {
        float s, c;
        hd_sincosf(kf->order[b] * d_angle_rad, &s, &c);
        unsigned k = 2u * b;
        kf->phi[k][k] = c;
        kf->phi[k][k + 1u] = s;
        kf->phi[k + 1u][k] = -s;
        kf->phi[k + 1u][k + 1u] = c;
    }
    if (n > 2u * kf->blocks) {
        kf->phi[n - 1u][n - 1u] = 1.0f;
    }
}

float dense_kf_step(dense_kf_t *kf, float y, float d_angle_rad)
{
    unsigned n = kf->n;
    float pct[DENSE_KF_MAX_STATES];          /* P C' */
    float k[DENSE_KF_MAX_STATES];            /* Phi P C' / S */
    float xn[DENSE_KF_MAX_STATES];
    float a[DENSE_KF_MAX_STATES][DENSE_KF_MAX_STATES]; /* Phi P */

    build_phi(kf, d_angle_rad);

    float y_hat = 0.0f;
    for (unsigned i = 0; i < n; i++) {
        y_hat += kf->c[i] * kf->x[i];
    }
    float e = y - y_hat;
    for (unsigned i = 0; i < n; i++) {
        float acc = 0.0f;
        for (unsigned j = 0; j < n; j++) {
            acc += kf->p[i][j] * kf->c[j];
        }
        pct[i] = acc;
    }
    float s = kf->r;
    for (unsigned i = 0; i < n; i++) {
        s += kf->c[i] * pct[i];
    }
    for (unsigned i = 0; i < n; i++) {
        float acc = 0.0f;
        for (unsigned j = 0; j < n; j++) {
            acc += kf->phi[i][j] * pct[j];
        }
        k[i] = acc / s;
    }
    for (unsigned i = 0; i < n; i++) {
        float acc = 0.0f;
        for (unsigned j = 0; j < n; j++) {
            acc += kf->phi[i][j] * kf->x[j];
        }
        xn[i] = acc + k[i] * e;
    }
    for (unsigned i = 0; i < n; i++) {
        kf->x[i] = xn[i];
    }
    /* A = Phi P */
    for (unsigned i = 0; i < n; i++) {
        for (unsigned j = 0; j < n; j++) {
            float acc = 0.0f;
            for (unsigned m = 0; m < n; m++) {
                acc += kf->phi[i][m] * kf->p[m][j];
            }
            a[i][j] = acc;
        }
    }
    /* P = A Phi' + Q - K S K' */
    for (unsigned i = 0; i < n; i++) {
        for (unsigned j = 0; j < n; j++) {
            float acc = 0.0f;
            for (unsigned m = 0; m < n; m++) {
                acc += a[i][m] * kf->phi[j][m];
            }
            kf->p[i][j] = acc + kf->q[i][j] - k[i] * s * k[j];
        }
    }
    return y_hat;
}
