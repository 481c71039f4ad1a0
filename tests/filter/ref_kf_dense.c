/* Dense double-precision reference of equations 8-10 (see ref_kf_dense.h). */
#include "ref_kf_dense.h"

#include <math.h>
#include <string.h>

#define N REF_KF_MAX_N
#define REF_PI 3.14159265358979323846

typedef double mat_t[N][N];

static void mat_mul(int n, mat_t a, mat_t b, mat_t out) /* out = a b */
{
    mat_t t;
    for (int i = 0; i < n; i++)
        for (int j = 0; j < n; j++) {
            double s = 0.0;
            for (int k = 0; k < n; k++)
                s += a[i][k] * b[k][j];
            t[i][j] = s;
        }
    memcpy(out, t, sizeof(t));
}

static void mat_transpose(int n, mat_t a, mat_t out)
{
    for (int i = 0; i < n; i++)
        for (int j = 0; j < n; j++)
            out[j][i] = a[i][j];
}

/* Phase advance of configured block b over this step (header: "Each block is
 * locked to one reference"). */
static double block_theta(const hd_kf_config_t *cfg, int b, const hd_kf_input_t *in)
{
    const hd_kf_block_config_t *bc = &cfg->blocks[b];
    double inc_m = isfinite(in->d_motor_angle_rad) ? (double)in->d_motor_angle_rad : 0.0;
    double inc_o = isfinite(in->d_output_angle_rad) ? (double)in->d_output_angle_rad : 0.0;
    switch (bc->lock) {
    case HD_KF_LOCK_MOTOR:
        return (double)bc->order * inc_m;
    case HD_KF_LOCK_OUTPUT:
        return (double)bc->order * inc_o;
    default:
        return 2.0 * REF_PI * (double)bc->order * (double)cfg->ts_s;
    }
}

/* Initial variance of a block: output-locked blocks have their own. */
static double block_p0(const ref_kf_t *r, int b)
{
    return (double)(r->cfg.blocks[b].lock == HD_KF_LOCK_OUTPUT ? r->cfg.output_p0_nm2
                                                               : r->cfg.p0_nm2);
}

void ref_kf_init(ref_kf_t *r, const hd_kf_config_t *cfg)
{
    memset(r, 0, sizeof(*r));
    r->cfg = *cfg;
    for (int b = 0; b < cfg->block_count; b++)
        if (cfg->blocks[b].enabled)
            r->block_of_slot[r->nb++] = b;
    r->n = 2 * r->nb;
    r->offset_slot = -1;
    r->jump_override = -1;
    r->jump_rearm = (int)fmax(1.0, floor((double)HD_KF_JUMP_REARM_S / (double)cfg->ts_s + 0.5));
    r->jump_credit = (int)HD_KF_JUMP_BURST;
    if (cfg->offset_enabled)
        r->offset_slot = r->n++;
    for (int s = 0; s < r->nb; s++)
        r->P[2 * s][2 * s] = r->P[2 * s + 1][2 * s + 1] = block_p0(r, r->block_of_slot[s]);
    if (r->offset_slot >= 0)
        r->P[r->offset_slot][r->offset_slot] = (double)cfg->p0_nm2;
}

/* What sample k's increments decide for its step (hd_kf.h, "Per-block
 * rules"): Phi(k), Q(k), the row C(k), the gain fractions and the freezes.
 * Restarts a block whose phase is lost. */
typedef struct {
    mat_t phi;
    double q[N];    /* diagonal of Q */
    double c[N];    /* measurement row */
    double gain[N]; /* gain fraction per state: 1 (optimal) or below */
} plan_t;

/* Load-dependent ripple: the C entry of motor-locked blocks is
 * 1 + k |T_ref|.  T_ref starts at T_exp (+ the offset when it is real
 * torque and has been primed) and then moves towards that value by the
 * motor's motion fraction min(1, |d motor| / q_motion_ref): held at
 * standstill.  A non-finite T_exp makes y non-finite (no correction); it
 * then adds nothing to T_ref. */
static double load_row(ref_kf_t *r, const hd_kf_input_t *in)
{
    if (!(r->cfg.ripple_load_coeff_per_nm > 0.0f))
        return 1.0;
    double t_now = isfinite(in->torque_expected_nm) ? (double)in->torque_expected_nm : 0.0;
    if (r->offset_slot >= 0 && !r->cfg.offset_is_sensor_error && r->offset_primed)
        t_now += r->x[r->offset_slot];
    if (!r->load_ref_primed) {
        r->load_ref = t_now;
        r->load_ref_primed = 1;
    } else {
        double dm = isfinite(in->d_motor_angle_rad) ? fabs((double)in->d_motor_angle_rad) : 0.0;
        double ref = (double)r->cfg.q_motion_ref_rad;
        double f = ref > 0.0 ? fmin(1.0, dm / ref) : 1.0;
        r->load_ref += f * (t_now - r->load_ref);
    }
    return 1.0 + (double)r->cfg.ripple_load_coeff_per_nm * fabs(r->load_ref);
}

static void make_plan(ref_kf_t *r, const hd_kf_input_t *in, plan_t *m, ref_kf_output_t *out)
{
    memset(m, 0, sizeof(*m));
    for (int i = 0; i < N; i++)
        m->gain[i] = 1.0;
    const double c_load = load_row(r, in);
    out->load_scale = c_load;
    for (int s = 0; s < r->nb; s++) {
        int b = r->block_of_slot[s];
        double th = block_theta(&r->cfg, b, in);
        int i = 2 * s;
        m->phi[i][i] = cos(th);
        m->phi[i][i + 1] = sin(th);
        m->phi[i + 1][i] = -sin(th);
        m->phi[i + 1][i + 1] = cos(th);
        /* Angle-locked process noise scales with the angle travelled. */
        double q_scale = 1.0, ref = (double)r->cfg.q_motion_ref_rad;
        if (ref > 0.0 && r->cfg.blocks[b].lock != HD_KF_LOCK_FIXED)
            q_scale = fmin(1.0, fabs(th) / ref);
        m->q[i] = m->q[i + 1] = (double)r->cfg.blocks[b].q_nm2 * q_scale;
        /* A motor-locked block learns as it turns: its gain is scaled by
         * the same motion fraction; an output-locked block learns at
         * output_learn_scale, which scales its q too (hd_kf.h). */
        if (r->cfg.blocks[b].lock == HD_KF_LOCK_MOTOR)
            m->gain[i] = m->gain[i + 1] = q_scale;
        if (r->cfg.blocks[b].lock == HD_KF_LOCK_OUTPUT) {
            m->gain[i] = m->gain[i + 1] = (double)r->cfg.output_learn_scale;
            m->q[i] = m->q[i + 1] = m->q[i] * (double)r->cfg.output_learn_scale;
        }
        if (r->held[s]) {
            /* disabled at run time: held like a frozen block, not reported */
            m->q[i] = m->q[i + 1] = 0.0;
            m->gain[i] = m->gain[i + 1] = 0.0;
            continue;
        }
        if (fabs(th) > (double)r->cfg.nyquist_fraction * REF_PI) {
            /* Held: unobserved (C = 0), uncorrected (gain 0), no process
             * noise, still turned by Phi (hd_kf.h, "Nyquist"). */
            out->frozen_mask |= 1u << b;
            m->q[i] = m->q[i + 1] = 0.0;
            m->gain[i] = m->gain[i + 1] = 0.0;
            if (fabs(th) > (double)HD_KF_PHASE_LOST_RAD) {
                /* phase lost (an encoder fault): restart from 0 with p0 */
                for (int k = i; k < i + 2; k++) {
                    r->x[k] = 0.0;
                    for (int j = 0; j < r->n; j++)
                        r->P[k][j] = r->P[j][k] = 0.0;
                    r->P[k][k] = block_p0(r, b);
                }
            }
        } else {
            m->c[i] = r->cfg.blocks[b].lock == HD_KF_LOCK_MOTOR ? c_load : 1.0;
        }
    }
    if (r->offset_slot >= 0) {
        int o = r->offset_slot;
        m->phi[o][o] = 1.0;
        m->q[o] = (double)r->cfg.offset_q_nm2;
        m->c[o] = 1.0;
    }
    if (out->frozen_mask)
        out->status |= HD_KF_STATUS_FROZEN;
}

/* Time update: x <- Phi x, P <- Phi P Phi' + Q. */
static void time_update(ref_kf_t *r, const plan_t *m)
{
    const int n = r->n;
    mat_t phi, phit, tmp;
    double px[N];
    memcpy(phi, m->phi, sizeof(phi));
    mat_transpose(n, phi, phit);
    for (int i = 0; i < n; i++) {
        px[i] = 0.0;
        for (int j = 0; j < n; j++)
            px[i] += phi[i][j] * r->x[j];
    }
    memcpy(r->x, px, sizeof(px));
    mat_mul(n, phi, r->P, tmp);
    mat_mul(n, tmp, phit, r->P);
    for (int i = 0; i < n; i++)
        r->P[i][i] += m->q[i];
}

/* Outputs from the prior (x, P as they are), then the measurement update
 * with the gain K = F P C' / S and the Joseph covariance
 * P <- (I - K C) P (I - K C)' + K R K' (valid for any gain; the optimal
 * update when F = I).  A non-finite sample is not used. */
static void measurement_update(ref_kf_t *r, const hd_kf_input_t *in, const plan_t *m,
                               ref_kf_output_t *out)
{
    const int n = r->n;
    double ripple = 0.0;
    for (int s = 0; s < r->nb; s++) {
        int i = 2 * s;
        ripple += m->c[i] * r->x[i]; /* c = 0 for a frozen block */
        out->amplitude_nm[r->block_of_slot[s]] =
            m->c[i] * sqrt(r->x[i] * r->x[i] + r->x[i + 1] * r->x[i + 1]);
    }
    double y = (double)in->torque_meas_nm - (double)in->torque_expected_nm;
    if (r->offset_slot >= 0 && !r->offset_primed && isfinite(y)) {
        r->x[r->offset_slot] = y - ripple;
        r->offset_primed = 1;
    }
    double offset = r->offset_slot >= 0 ? r->x[r->offset_slot] : 0.0;
    double cx = 0.0; /* C x, straight from the row */
    for (int i = 0; i < n; i++)
        cx += m->c[i] * r->x[i];
    double cpc = 0.0;
    for (int i = 0; i < n; i++)
        for (int j = 0; j < n; j++)
            cpc += m->c[i] * r->P[i][j] * m->c[j];
    /* R of this sample: the sensor's plus T_exp's own variance (the
     * contract in hd_kf.h: negative or NaN is 0, capped at 1e12) */
    const double v = (double)in->torque_expected_var_nm2;
    const double r_k = (double)r->cfg.r_nm2 + (v > 0.0 ? fmin(v, 1e12) : 0.0);
    double s_var = r_k + cpc;
    /* Offset jump: an innovation beyond both the absolute threshold and
     * 4 sigma inflates the offset variance by e^2 before the update. */
    out->jump_margin_rel = INFINITY;
    if (r->offset_slot >= 0 && r->cfg.offset_jump_nm > 0.0f && isfinite(y)) {
        double e0 = y - cx;
        double thr = fmax((double)r->cfg.offset_jump_nm, 4.0 * sqrt(s_var));
        /* at most HD_KF_JUMP_BURST jumps, back after jump_rearm steps in a
         * row within the gate (each step beyond it restarts the count) */
        const int beyond = fabs(e0) > thr;
        out->jump_own_decision = beyond && r->jump_credit > 0;
        out->jump_margin_rel = fabs(fabs(e0) - thr) / thr;
        int jump = r->jump_override >= 0 ? r->jump_override : out->jump_own_decision;
        if (beyond || jump) {
            r->jump_hold = r->jump_rearm;
        } else if (r->jump_hold > 0 && --r->jump_hold == 0) {
            r->jump_credit = (int)HD_KF_JUMP_BURST;
        }
        if (jump && r->jump_credit > 0) {
            r->jump_credit--;
        }
        if (jump) {
            r->P[r->offset_slot][r->offset_slot] += e0 * e0;
            s_var += e0 * e0;
            out->status |= HD_KF_STATUS_OFFSET_JUMP;
        }
    }
    out->ripple_nm = ripple;
    out->offset_nm = offset;
    out->innovation_var_nm2 = s_var;
    out->torque_filtered_nm = (double)in->torque_meas_nm - ripple -
                              (r->cfg.offset_is_sensor_error ? offset : 0.0);
    if (!isfinite(y)) {
        out->status |= HD_KF_STATUS_BAD_INPUT;
        return;
    }
    double e = y - cx;
    out->innovation_nm = e;
    double k_e[N];
    for (int i = 0; i < n; i++) {
        double pc = 0.0;
        for (int j = 0; j < n; j++)
            pc += r->P[i][j] * m->c[j];
        k_e[i] = m->gain[i] * pc / s_var;
    }
    for (int i = 0; i < n; i++)
        r->x[i] += k_e[i] * e;
    mat_t a, at, tmp;
    for (int i = 0; i < n; i++)
        for (int j = 0; j < n; j++)
            a[i][j] = (i == j ? 1.0 : 0.0) - k_e[i] * m->c[j];
    mat_transpose(n, a, at);
    mat_mul(n, a, r->P, tmp);
    mat_mul(n, tmp, at, r->P);
    for (int i = 0; i < n; i++)
        for (int j = 0; j < n; j++)
            r->P[i][j] += k_e[i] * r_k * k_e[j];
}

/* Ceiling on the stored P: P <- D P D.  A block's two states share D =
 * sqrt(p_max / lambda_max) when the largest eigenvalue of its 2x2
 * covariance block exceeds p_max (a bound on the block's variance in every
 * direction, whatever the phase); the offset's D = sqrt(p_max / P_oo). */
static void apply_ceiling(ref_kf_t *r, ref_kf_output_t *out)
{
    const int n = r->n;
    double d[N];
    int clamped = 0;
    const double p_max = (double)r->cfg.p_max_nm2;
    for (int i = 0; i < n; i++)
        d[i] = 1.0;
    for (int s = 0; s < r->nb; s++) {
        int i = 2 * s;
        double mid = 0.5 * (r->P[i][i] + r->P[i + 1][i + 1]);
        double h = 0.5 * (r->P[i][i] - r->P[i + 1][i + 1]);
        double lmax = mid + sqrt(h * h + r->P[i][i + 1] * r->P[i][i + 1]);
        if (lmax > p_max) {
            d[i] = d[i + 1] = sqrt(p_max / lmax);
            clamped = 1;
        }
    }
    if (r->offset_slot >= 0 && r->P[r->offset_slot][r->offset_slot] > p_max) {
        d[r->offset_slot] = sqrt(p_max / r->P[r->offset_slot][r->offset_slot]);
        clamped = 1;
    }
    if (clamped) {
        out->status |= HD_KF_STATUS_P_CLAMPED;
        for (int i = 0; i < n; i++)
            for (int j = 0; j < n; j++)
                r->P[i][j] *= d[i] * d[j];
    }
}

void ref_kf_step(ref_kf_t *r, const hd_kf_input_t *in, ref_kf_output_t *out)
{
    static plan_t m; /* static: a few KB */
    memset(out, 0, sizeof(*out));
    make_plan(r, in, &m, out);
    time_update(r, &m);
    measurement_update(r, in, &m, out);
    apply_ceiling(r, out);
}

void ref_kf_step_update_first(ref_kf_t *r, const hd_kf_input_t *in, ref_kf_output_t *out)
{
    static plan_t m;
    memset(out, 0, sizeof(*out));
    make_plan(r, in, &m, out);
    measurement_update(r, in, &m, out);
    time_update(r, &m);
    apply_ceiling(r, out);
}

/* Integral order 1..255 of an enabled motor/output block, else 0. */
static int ref_profile_order(const hd_kf_block_config_t *bc)
{
    if (bc->lock == HD_KF_LOCK_FIXED || bc->order < 1.0f || bc->order > 255.0f ||
        floor((double)bc->order) != (double)bc->order)
        return 0;
    return (int)bc->order;
}

/* alpha: the lock angle of the sample the state is at (the caller's). */
static double ref_alpha(int lock, double motor_angle, double output_angle)
{
    return lock == HD_KF_LOCK_MOTOR ? motor_angle : output_angle;
}

void ref_kf_set_block_enabled(ref_kf_t *r, int b, int enabled)
{
    int s = 0;
    while (s < r->nb && r->block_of_slot[s] != b)
        s++;
    r->cfg.blocks[b].enabled = (uint8_t)(enabled != 0);
    if (!enabled) {
        if (s < r->nb)
            r->held[s] = 1;
        return;
    }
    if (s == r->nb) {
        /* not in the model: insert its two states before the first slot of
         * a later configured block (or the offset) */
        s = 0;
        while (s < r->nb && r->block_of_slot[s] < b)
            s++;
        const int at = 2 * s, n = r->n;
        for (int i = n + 1; i >= at + 2; i--) {
            r->x[i] = r->x[i - 2];
            for (int j = 0; j < n + 2; j++)
                r->P[i][j] = r->P[i - 2][j];
        }
        for (int j = n + 1; j >= at + 2; j--)
            for (int i = 0; i < n + 2; i++)
                r->P[i][j] = r->P[i][j - 2];
        for (int k = r->nb; k > s; k--) {
            r->block_of_slot[k] = r->block_of_slot[k - 1];
            r->held[k] = r->held[k - 1];
        }
        r->block_of_slot[s] = b;
        r->nb++;
        r->n += 2;
        if (r->offset_slot >= 0)
            r->offset_slot += 2;
    }
    r->held[s] = 0;
    for (int k = 2 * s; k < 2 * s + 2; k++) {
        r->x[k] = 0.0;
        for (int j = 0; j < r->n; j++)
            r->P[k][j] = r->P[j][k] = 0.0;
        r->P[k][k] = block_p0(r, b);
    }
}

int ref_kf_active_index(const ref_kf_t *r, int i)
{
    for (int s = 0; s < r->nb; s++) {
        if (r->held[s])
            continue;
        if (i < 2)
            return 2 * s + i;
        i -= 2;
    }
    return (i == 0 && r->offset_slot >= 0) ? r->offset_slot : -1;
}

int ref_kf_active_count(const ref_kf_t *r)
{
    int n = r->offset_slot >= 0 ? 1 : 0;
    for (int s = 0; s < r->nb; s++)
        n += r->held[s] ? 0 : 2;
    return n;
}

int ref_kf_profile_export(const ref_kf_t *r, double motor_angle_rad, double output_angle_rad,
                          int lock[], int order[], double a[], double b[])
{
    int n = 0;
    for (int s = 0; s < r->nb; s++) {
        const hd_kf_block_config_t *bc = &r->cfg.blocks[r->block_of_slot[s]];
        int k = r->held[s] ? 0 : ref_profile_order(bc);
        if (k == 0)
            continue;
        double t = k * ref_alpha(bc->lock, motor_angle_rad, output_angle_rad);
        double x1 = r->x[2 * s], x2 = r->x[2 * s + 1];
        /* x = R(t) (a, b)'  =>  (a, b)' = R(t)' x */
        lock[n] = bc->lock;
        order[n] = k;
        a[n] = cos(t) * x1 - sin(t) * x2;
        b[n] = sin(t) * x1 + cos(t) * x2;
        n++;
    }
    return n;
}

int ref_kf_profile_import(ref_kf_t *r, int lines, const int lock[], const int order[],
                          const double a[], const double b[], double motor_angle_rad,
                          double output_angle_rad, double var_nm2)
{
    int used[HD_KF_MAX_BLOCKS] = {0}, count = 0;
    for (int i = 0; i < lines; i++) {
        for (int s = 0; s < r->nb; s++) {
            const hd_kf_block_config_t *bc = &r->cfg.blocks[r->block_of_slot[s]];
            if (used[s] || r->held[s] || bc->lock != lock[i] || ref_profile_order(bc) != order[i])
                continue;
            double t = order[i] * ref_alpha(bc->lock, motor_angle_rad, output_angle_rad);
            for (int k = 2 * s; k < 2 * s + 2; k++)
                for (int j = 0; j < r->n; j++)
                    r->P[k][j] = r->P[j][k] = 0.0;
            r->P[2 * s][2 * s] = r->P[2 * s + 1][2 * s + 1] = var_nm2;
            r->x[2 * s] = cos(t) * a[i] + sin(t) * b[i];
            r->x[2 * s + 1] = -sin(t) * a[i] + cos(t) * b[i];
            used[s] = 1;
            count++;
            break;
        }
    }
    return count;
}
