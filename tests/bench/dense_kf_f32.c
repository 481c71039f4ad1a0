/* Dense float32 textbook Kalman filter (see dense_kf_f32.h). */
#include "dense_kf_f32.h"

#include <stddef.h>

#include "hd_trig.h"

#define N DENSE_KF_MAX_N
#define TWO_PI_F 6.28318530718f

typedef float mat_t[N][N];

/* out = a b (n x n); out must not alias a or b. */
static void mat_mul(int n, const mat_t a, const mat_t b, mat_t out)
{
    for (int i = 0; i < n; i++) {
        for (int j = 0; j < n; j++) {
            float s = 0.0f;
            for (int k = 0; k < n; k++) {
                s += a[i][k] * b[k][j];
            }
            out[i][j] = s;
        }
    }
}

static float block_theta(const hd_kf_config_t *cfg, int b, const hd_kf_input_t *in)
{
    const hd_kf_block_config_t *bc = &cfg->blocks[b];
    if (bc->lock == HD_KF_LOCK_MOTOR) {
        return bc->order * in->d_motor_angle_rad;
    }
    if (bc->lock == HD_KF_LOCK_OUTPUT) {
        return bc->order * in->d_output_angle_rad;
    }
    return TWO_PI_F * bc->order * cfg->ts_s;
}

void dense_kf_f32_init(dense_kf_f32_t *kf, const hd_kf_config_t *cfg)
{
    *kf = (dense_kf_f32_t){0};
    kf->cfg = *cfg;
    for (int b = 0; b < cfg->block_count; b++) {
        if (cfg->blocks[b].enabled) {
            kf->block_of_slot[kf->nb++] = b;
        }
    }
    kf->n = 2 * kf->nb;
    kf->offset_slot = -1;
    if (cfg->offset_enabled) {
        kf->offset_slot = kf->n++;
    }
    for (int i = 0; i < kf->n; i++) {
        kf->p[i][i] = cfg->p0_nm2;
    }
}

/* Builds the dense Phi, the diagonal of Q and the measurement row C. */
static void build_model(const dense_kf_f32_t *kf, const hd_kf_input_t *in,
                        mat_t phi, float q_diag[N], float c[N])
{
    for (int i = 0; i < kf->n; i++) {
        for (int j = 0; j < kf->n; j++) {
            phi[i][j] = 0.0f;
        }
        c[i] = 0.0f;
        q_diag[i] = 0.0f;
    }
    for (int s = 0; s < kf->nb; s++) {
        const int b = kf->block_of_slot[s];
        const int i = 2 * s;
        float sn;
        float cs;
        hd_sincosf(block_theta(&kf->cfg, b, in), &sn, &cs);
        phi[i][i] = cs;
        phi[i][i + 1] = sn;
        phi[i + 1][i] = -sn;
        phi[i + 1][i + 1] = cs;
        q_diag[i] = kf->cfg.blocks[b].q_nm2;
        q_diag[i + 1] = kf->cfg.blocks[b].q_nm2;
        c[i] = 1.0f;
    }
    if (kf->offset_slot >= 0) {
        phi[kf->offset_slot][kf->offset_slot] = 1.0f;
        q_diag[kf->offset_slot] = kf->cfg.offset_q_nm2;
        c[kf->offset_slot] = 1.0f;
    }
}

void dense_kf_f32_step(dense_kf_f32_t *kf, const hd_kf_input_t *in,
                       dense_kf_f32_output_t *out)
{
    const int n = kf->n;
    mat_t phi;
    mat_t phit;
    mat_t a;
    mat_t tmp;
    float q_diag[N];
    float c[N];
    float pc[N];
    float k[N];
    float px[N];

    build_model(kf, in, phi, q_diag, c);

    /* Outputs from the prior x(k|k-1). */
    float cx = 0.0f;
    float ripple = 0.0f;
    for (int i = 0; i < n; i++) {
        cx += c[i] * kf->x[i];
        if (i != kf->offset_slot) {
            ripple += c[i] * kf->x[i];
        }
    }
    const float offset = kf->offset_slot >= 0 ? kf->x[kf->offset_slot] : 0.0f;
    const float e = in->torque_meas_nm - in->torque_expected_nm - cx;
    out->ripple_nm = ripple;
    out->innovation_nm = e;
    out->torque_filtered_nm = in->torque_meas_nm - ripple -
                              (kf->cfg.offset_is_sensor_error ? offset : 0.0f);

    /* S = C P C' + R;  K = Phi P C' / S   (9) */
    float s_var = kf->cfg.r_nm2;
    for (int i = 0; i < n; i++) {
        pc[i] = 0.0f;
        for (int j = 0; j < n; j++) {
            pc[i] += kf->p[i][j] * c[j];
        }
        s_var += c[i] * pc[i];
    }
    for (int i = 0; i < n; i++) {
        k[i] = 0.0f;
        for (int j = 0; j < n; j++) {
            k[i] += phi[i][j] * pc[j];
        }
        k[i] /= s_var;
    }
    /* x <- Phi x + K e   (8) */
    for (int i = 0; i < n; i++) {
        px[i] = k[i] * e;
        for (int j = 0; j < n; j++) {
            px[i] += phi[i][j] * kf->x[j];
        }
    }
    for (int i = 0; i < n; i++) {
        kf->x[i] = px[i];
    }
    /* P <- (Phi - K C) P Phi' + Q   (10) */
    for (int i = 0; i < n; i++) {
        for (int j = 0; j < n; j++) {
            a[i][j] = phi[i][j] - k[i] * c[j];
            phit[j][i] = phi[i][j];
        }
    }
    mat_mul(n, (const float(*)[N])a, (const float(*)[N])kf->p, tmp);
    mat_mul(n, (const float(*)[N])tmp, (const float(*)[N])phit, kf->p);
    for (int i = 0; i < n; i++) {
        kf->p[i][i] += q_diag[i];
    }
}
