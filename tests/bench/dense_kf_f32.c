/* Dense float32 textbook Kalman filter (see dense_kf_f32.h). */
#include "dense_kf_f32.h"

#include <math.h>
#include <stddef.h>

#include "hd_trig.h"

#define N DENSE_KF_MAX_N

typedef float mat_t[N][N];

/* out = a b (n x n); out must not alias a or b. */
static void mul(int n, const mat_t a, const mat_t b, mat_t out)
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

/* out = a b' (n x n): the Joseph form's right factor without forming b'. */
static void mul_transposed(int n, const mat_t a, const mat_t b, mat_t out)
{
    for (int i = 0; i < n; i++) {
        for (int j = 0; j < n; j++) {
            float s = 0.0f;
            for (int k = 0; k < n; k++) {
                s += a[i][k] * b[j][k];
            }
            out[i][j] = s;
        }
    }
}

static float block_p0(const dense_kf_f32_t *kf, int b)
{
    return kf->cfg.blocks[b].lock == HD_KF_LOCK_OUTPUT ? kf->cfg.output_p0_nm2 : kf->cfg.p0_nm2;
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
    for (int s = 0; s < kf->nb; s++) {
        kf->p[2 * s][2 * s] = kf->p[2 * s + 1][2 * s + 1] = block_p0(kf, kf->block_of_slot[s]);
    }
    if (kf->offset_slot >= 0) {
        kf->p[kf->offset_slot][kf->offset_slot] = cfg->p0_nm2;
    }
}

typedef struct {
    mat_t phi;
    float q[N];    /* diagonal of Q */
    float c[N];    /* measurement row */
    float gain[N]; /* diagonal of F */
} model_t;

/* Phi, Q, C and F of this step (hd_kf.h, "Per-block rules"); restarts a
 * block whose phase is lost. */
static void build_model(dense_kf_f32_t *kf, const hd_kf_input_t *in, model_t *m)
{
    const hd_kf_config_t *cfg = &kf->cfg;
    const float dm = (in->d_motor_angle_rad - in->d_motor_angle_rad == 0.0f) ? in->d_motor_angle_rad
                                                                            : 0.0f;
    const float d_o = (in->d_output_angle_rad - in->d_output_angle_rad == 0.0f)
                          ? in->d_output_angle_rad
                          : 0.0f;
    for (int i = 0; i < kf->n; i++) {
        for (int j = 0; j < kf->n; j++) {
            m->phi[i][j] = 0.0f;
        }
        m->q[i] = m->c[i] = 0.0f;
        m->gain[i] = 1.0f;
    }
    for (int s = 0; s < kf->nb; s++) {
        const int b = kf->block_of_slot[s], i = 2 * s;
        const hd_kf_block_config_t *bc = &cfg->blocks[b];
        float theta = HD_TWO_PI_F * bc->order * cfg->ts_s;
        float motion = 1.0f, gain = 1.0f, q = bc->q_nm2;
        if (bc->lock != HD_KF_LOCK_FIXED) {
            theta = bc->order * (bc->lock == HD_KF_LOCK_MOTOR ? dm : d_o);
            if (cfg->q_motion_ref_rad > 0.0f && fabsf(theta) < cfg->q_motion_ref_rad) {
                motion = fabsf(theta) / cfg->q_motion_ref_rad;
            }
            q *= motion;
            gain = bc->lock == HD_KF_LOCK_MOTOR ? motion : cfg->output_learn_scale;
            if (bc->lock == HD_KF_LOCK_OUTPUT) {
                q *= cfg->output_learn_scale;
            }
        }
        float sn, cs;
        hd_sincosf(theta, &sn, &cs);
        m->phi[i][i] = m->phi[i + 1][i + 1] = cs;
        m->phi[i][i + 1] = sn;
        m->phi[i + 1][i] = -sn;
        m->c[i] = 1.0f;
        if (fabsf(theta) > cfg->nyquist_fraction * HD_PI_F) {
            m->c[i] = 0.0f;
            gain = q = 0.0f;
            if (fabsf(theta) > HD_KF_PHASE_LOST_RAD) {
                for (int k = i; k < i + 2; k++) {
                    kf->x[k] = 0.0f;
                    for (int j = 0; j < kf->n; j++) {
                        kf->p[k][j] = kf->p[j][k] = 0.0f;
                    }
                    kf->p[k][k] = block_p0(kf, b);
                }
            }
        }
        m->q[i] = m->q[i + 1] = q;
        m->gain[i] = m->gain[i + 1] = gain;
    }
    if (kf->offset_slot >= 0) {
        const int o = kf->offset_slot;
        m->phi[o][o] = 1.0f;
        m->q[o] = cfg->offset_q_nm2;
        m->c[o] = 1.0f;
    }
}

/* P <- a P b' (n x n), through the scratch t. */
static void congruence(int n, const mat_t a, mat_t p, const mat_t b, mat_t t)
{
    mul(n, a, (const float(*)[N])p, t);
    mul_transposed(n, (const float(*)[N])t, b, p);
}

void dense_kf_f32_step(dense_kf_f32_t *kf, const hd_kf_input_t *in,
                       dense_kf_f32_output_t *out)
{
    const int n = kf->n;
    static model_t m; /* static: the benchmark runs one filter at a time */
    mat_t t;
    float pc[N], k[N], px[N];
    build_model(kf, in, &m);

    /* Time update by this sample's increments: x <- Phi x, P <- Phi P Phi' + Q */
    for (int i = 0; i < n; i++) {
        px[i] = 0.0f;
        for (int j = 0; j < n; j++) {
            px[i] += m.phi[i][j] * kf->x[j];
        }
    }
    for (int i = 0; i < n; i++) {
        kf->x[i] = px[i];
    }
    congruence(n, (const float(*)[N])m.phi, kf->p, (const float(*)[N])m.phi, t);
    for (int i = 0; i < n; i++) {
        kf->p[i][i] += m.q[i];
    }

    /* Outputs from the prior. */
    const float y = in->torque_meas_nm - in->torque_expected_nm;
    const int valid = fabsf(y) <= HD_KF_MAX_ABS_Y_NM;
    float ripple = 0.0f;
    for (int s = 0; s < kf->nb; s++) {
        ripple += m.c[2 * s] * kf->x[2 * s];
    }
    if (kf->offset_slot >= 0 && !kf->offset_primed && valid) {
        kf->x[kf->offset_slot] = y - ripple;
        kf->offset_primed = 1;
    }
    const float offset = kf->offset_slot >= 0 ? kf->x[kf->offset_slot] : 0.0f;
    const float e = valid ? y - ripple - offset : 0.0f;
    out->ripple_nm = ripple;
    out->innovation_nm = e;
    out->torque_filtered_nm = in->torque_meas_nm - ripple -
                              (kf->cfg.offset_is_sensor_error ? offset : 0.0f);

    /* S = C P C' + R; the offset-jump gate widens P_oo first. */
    const float v = in->torque_expected_var_nm2; /* R + v, v in [0, ceiling] (hd_kf.h) */
    const float v_cap = v < HD_KF_MAX_EXPECTED_VAR_NM2 ? v : HD_KF_MAX_EXPECTED_VAR_NM2;
    float s_var = kf->cfg.r_nm2 + (v > 0.0f ? v_cap : 0.0f);
    for (int i = 0; i < n; i++) {
        pc[i] = 0.0f;
        for (int j = 0; j < n; j++) {
            pc[i] += kf->p[i][j] * m.c[j];
        }
        s_var += m.c[i] * pc[i];
    }
    if (valid && kf->offset_slot >= 0 && kf->cfg.offset_jump_nm > 0.0f &&
        e * e > kf->cfg.offset_jump_nm * kf->cfg.offset_jump_nm && e * e > 16.0f * s_var) {
        const int o = kf->offset_slot;
        kf->p[o][o] += e * e;
        pc[o] += e * e;
        s_var += e * e;
    }
    if (valid) {
        /* K = F P C' / S;  x <- x + K e */
        for (int i = 0; i < n; i++) {
            k[i] = m.gain[i] * pc[i] / s_var;
            kf->x[i] += k[i] * e;
        }
        /* P <- (I - K C) P (I - K C)' + K R K' (Joseph form), expanded with
         * g = P C' and S = C P C' + R: P - K g' - g K' + K S K' */
        for (int i = 0; i < n; i++) {
            for (int j = 0; j < n; j++) {
                kf->p[i][j] += -k[i] * pc[j] - pc[i] * k[j] + k[i] * s_var * k[j];
            }
        }
    }
    /* then symmetrise */
    for (int i = 0; i < n; i++) {
        for (int j = 0; j < i; j++) {
            kf->p[i][j] = kf->p[j][i] = 0.5f * (kf->p[i][j] + kf->p[j][i]);
        }
    }
    /* ceiling on the diagonal: P <- D P D, D_ii = sqrt(p_max / P_ii) */
    for (int i = 0; i < n; i++) {
        if (kf->p[i][i] > kf->cfg.p_max_nm2) {
            const float d = sqrtf(kf->cfg.p_max_nm2 / kf->p[i][i]);
            for (int j = 0; j < n; j++) {
                kf->p[i][j] *= d;
                kf->p[j][i] *= d;
            }
        }
    }
}
