/* hd_ctrl: the joint controller's law (hd_ctrl.h has the equations). */
#include "hd_ctrl.h"

#include <stddef.h>

#include "hd_ctrl_trig.h"

#define TWO_PI_F 6.28318530717958647692f
#define PI_F 3.14159265358979323846f
#define NOTCH_NYQUIST_SHARE 0.45f /* a notch above 0.45 / ts passes */

/* isfinite without a libm call: x - x is 0 only for finite x. */
static bool finite_f(float x)
{
    return (x - x) == 0.0f;
}

/* lo <= x <= hi, false for NaN. */
static bool within(float x, float lo, float hi)
{
    return x >= lo && x <= hi;
}

static float clampf(float x, float lo, float hi)
{
    return x < lo ? lo : (x > hi ? hi : x);
}

void hd_ctrl_config_default(hd_ctrl_config_t *cfg)
{
    if (cfg == NULL) {
        return;
    }
    *cfg = (hd_ctrl_config_t){
        .ts_s = 1e-3f,
        .gear_ratio = 100.0f,
        .kt_nm_per_a = 0.06f,
        /* the product feedback: docs/decisions/control-bandwidth.md, "Tuned against the wall" */
        .feedback = HD_CTRL_FB_NARROW,
        .torque_kp = 0.86f,          /* tools/bench --only control: docs/results/control.md, "Tuning" */
        .torque_ki_per_s = 27.0f,    /*   (the product feedback's tuned row) */
        .torque_ff = 1.0f,
        .torque_kd_s = 0.0015f,
        .integral_limit_nm = 7.69f,  /* tools/bench --only control, as the gains */
        /* a sweep on the simulated joint: docs/decisions/control-integral-schedule.md */
        .integral_stiffness_nm_rad = 6000.0f,
        .lowpass_hz = 50.0f,
        .lowpass_order = 1u,
        .notch_mask = 0u,
        .notch_width_hz = 10.0f,
        .artifact_mask = 0u,         /* the firmware sets it from the filter's model */
        .artifact_hz = 0.5f,
        .friction_nm = 0.0f,
        .friction_velocity_rad_s = 0.05f,
        .friction_rest_nm = 0.0f,
        .friction_rate_nm_s = 1.0f,
        .damp_nm_s_rad = 1.0f,
        .torque_limit_nm = 40.0f,
        .current_limit_a = 8.0f,
        .velocity_limit_rad_s = 6.0f,
        .velocity_gain_nm_s_rad = 20.0f,
        .position_min_rad = -100.0f,
        .position_max_rad = 100.0f,
    };
}

int hd_ctrl_config_check(const hd_ctrl_config_t *cfg)
{
    if (cfg == NULL) {
        return HD_CTRL_ERR_NULL;
    }
    const hd_ctrl_config_t *k = cfg;
    const bool ok =
        within(k->ts_s, 1e-5f, 0.1f) && within(k->gear_ratio, 1.0f, 1e5f) &&
        within(k->kt_nm_per_a, 1e-4f, 10.0f) && (unsigned)k->feedback < HD_CTRL_FB_COUNT &&
        within(k->torque_kp, 0.0f, HD_CTRL_TORQUE_GAIN_MAX) &&
        within(k->torque_ki_per_s, 0.0f, HD_CTRL_KI_MAX_PER_S) &&
        within(k->torque_ff, 0.0f, 1.0f) && within(k->torque_kd_s, 0.0f, HD_CTRL_TORQUE_KD_MAX_S) &&
        within(k->integral_limit_nm, 0.0f, 1e4f) &&
        within(k->integral_stiffness_nm_rad, 1.0f, HD_CTRL_INTEGRAL_STIFFNESS_MAX_NM_RAD) &&
        k->lowpass_hz > 0.0f &&
        k->lowpass_hz < 0.5f / k->ts_s &&
        (k->lowpass_order == 1u || k->lowpass_order == 2u || k->lowpass_order == 4u) &&
        within(k->notch_width_hz, 0.1f, 0.1f / k->ts_s) &&
        within(k->artifact_hz, 0.01f, 0.05f / k->ts_s) && within(k->friction_nm, 0.0f, 1000.0f) &&
        within(k->friction_velocity_rad_s, 1e-4f, 100.0f) &&
        within(k->friction_rest_nm, 0.0f, 1000.0f) &&
        within(k->friction_rate_nm_s, 1e-3f, 1e6f) &&
        within(k->damp_nm_s_rad, 0.0f, 1000.0f) && within(k->torque_limit_nm, 1e-3f, 1e4f) &&
        within(k->current_limit_a, 1e-3f, 1000.0f) &&
        within(k->velocity_limit_rad_s, 1e-3f, 1e4f) &&
        within(k->velocity_gain_nm_s_rad, 0.0f, 1e4f) &&
        within(k->position_min_rad, -1e6f, 1e6f) && within(k->position_max_rad, -1e6f, 1e6f) &&
        k->position_min_rad < k->position_max_rad;
    return ok ? HD_CTRL_OK : HD_CTRL_ERR_CONFIG;
}

void hd_ctrl_reset(hd_ctrl_t *c)
{
    if (c == NULL) {
        return;
    }
    c->integral_nm = 0.0f;
    c->fb_prev_nm = 0.0f;
    c->fb_primed = false;
    c->lowpass_nm = 0.0f;
    c->lowpass_primed = false; /* the low-pass and notch states are primed on first use */
    c->raw_notched_nm = 0.0f;
    c->sp_torque_prev_nm = 0.0f;
    c->sp_torque_primed = false;
    c->narrow_nm = 0.0f;
    c->narrow_ok = false;
    hd_artifact_reset(&c->artifact);
}

/* A Butterworth low-pass section (bilinear; k = tan(pi fc ts), quality q). */
static void butter_section(hd_ctrl_sos_t *b, float k, float q)
{
    const float norm = 1.0f / (1.0f + k / q + k * k);
    b->b0 = k * k * norm;
    b->b1 = 2.0f * b->b0;
    b->b2 = b->b0;
    b->a1 = 2.0f * (k * k - 1.0f) * norm;
    b->a2 = (1.0f - k / q + k * k) * norm;
}

static float biquad_step(const hd_ctrl_sos_t *b, hd_ctrl_sos_state_t *st, float x)
{
    const float y = b->b0 * x + st->s0;
    st->s0 = b->b1 * x - b->a1 * y + st->s1;
    st->s1 = b->b2 * x - b->a2 * y;
    return y;
}

/* The state a unity-DC-gain section holds in steady state at input x. */
static void biquad_prime(const hd_ctrl_sos_t *b, hd_ctrl_sos_state_t *st, float x)
{
    st->s1 = (b->b2 - b->a2) * x;
    st->s0 = (1.0f - b->b0) * x;
}

static void sos_pass(hd_ctrl_sos_t *b)
{
    b->b0 = 1.0f, b->b1 = b->b2 = b->a1 = b->a2 = 0.0f;
}

int hd_ctrl_plan(hd_ctrl_plan_t *p, const hd_ctrl_config_t *cfg)
{
    if (p == NULL || cfg == NULL) {
        return HD_CTRL_ERR_NULL;
    }
    const int rc = hd_ctrl_config_check(cfg);
    if (rc != HD_CTRL_OK) {
        return rc;
    }
    p->cfg = *cfg;
    const float wts = TWO_PI_F * cfg->lowpass_hz * cfg->ts_s;
    p->lowpass_alpha = wts / (1.0f + wts);
    /* Butterworth sections: the pole pairs' quality factors, 1 / (2 cos)
     * of their angles: order 2 one pair at 45 deg, order 4 at 22.5 and
     * 67.5 deg. */
    for (unsigned i = 0; i < HD_CTRL_BIQUAD_MAX; i++) {
        sos_pass(&p->butter[i]);
    }
    if (cfg->lowpass_order != 1u) {
        const float x = PI_F * cfg->lowpass_hz * cfg->ts_s;
        const float k = sin_poly(x) / cos_poly(x);
        if (cfg->lowpass_order == 2u) {
            butter_section(&p->butter[0], k, 0.70710678f);
        } else {
            butter_section(&p->butter[0], k, 0.54119610f);
            butter_section(&p->butter[1], k, 1.30656296f);
        }
    }
    p->notch_r = 1.0f - PI_F * cfg->notch_width_hz * cfg->ts_s;
    p->narrow_inv_rad_s = 1.0f / (4.0f * TWO_PI_F * cfg->artifact_hz);
    /* bit k-1 is order k: the lowest set bit's order, 1 without orders */
    p->artifact_k_min = cfg->artifact_mask != 0u
                            ? (uint8_t)(__builtin_ctz(cfg->artifact_mask) + 1)
                            : 1u;
    return HD_CTRL_OK;
}

void hd_ctrl_start(hd_ctrl_t *c, const hd_ctrl_plan_t *p)
{
    c->plan = p;
    hd_artifact_init(&c->artifact, p->cfg.artifact_mask, p->cfg.artifact_hz, p->cfg.ts_s);
    hd_ctrl_reset(c);
}

void hd_ctrl_replan(hd_ctrl_t *c, const hd_ctrl_plan_t *p)
{
    c->plan = p;
    hd_artifact_remask(&c->artifact, p->cfg.artifact_mask);
}

int hd_ctrl_init(hd_ctrl_t *c, hd_ctrl_plan_t *p, const hd_ctrl_config_t *cfg)
{
    if (c == NULL) {
        return HD_CTRL_ERR_NULL;
    }
    const int rc = hd_ctrl_plan(p, cfg);
    if (rc == HD_CTRL_OK) {
        hd_ctrl_start(c, p);
    }
    return rc;
}

bool hd_ctrl_setpoint_valid(const hd_ctrl_setpoint_t *sp)
{
    return sp != NULL && (unsigned)sp->mode < HD_CTRL_MODE_COUNT && finite_f(sp->torque_nm) &&
           finite_f(sp->position_rad) && finite_f(sp->velocity_rad_s) &&
           within(sp->kp_nm_rad, 0.0f, HD_CTRL_KP_MAX_NM_RAD) &&
           within(sp->kd_nm_s_rad, 0.0f, HD_CTRL_KD_MAX_NM_S_RAD);
}

static bool uses_torque_loop(hd_ctrl_mode_t m)
{
    return m == HD_CTRL_TORQUE || m == HD_CTRL_IMPEDANCE || m == HD_CTRL_ZERO_TORQUE;
}

/* The notches' coefficients for this tick's speed: zeros on the unit
 * circle at w0, poles at radius r, the numerator scaled to unity DC gain.
 * false: the notch passes this tick (w0 below its width or near Nyquist). */
static bool notch_tune(hd_ctrl_sos_t *b, float w0, float r, float w_min)
{
    if (!(w0 >= w_min && w0 <= NOTCH_NYQUIST_SHARE * TWO_PI_F)) {
        return false;
    }
    const float cw = cos_poly(w0);
    const float g = (1.0f - 2.0f * r * cw + r * r) / (2.0f - 2.0f * cw);
    b->b0 = g;
    b->b1 = -2.0f * cw * g;
    b->b2 = g;
    b->a1 = -2.0f * r * cw;
    b->a2 = r * r;
    return true;
}

/* The raw torque through the order notches (bounded: at most
 * HD_CTRL_NOTCH_MAX sections).  A passing notch keeps its state at the
 * torque, so it engages without a transient. */
static float notches(hd_ctrl_t *c, float raw, float v, bool prime)
{
    const hd_ctrl_config_t *k = &c->plan->cfg;
    const float w_motor = k->gear_ratio * (v < 0.0f ? -v : v) * k->ts_s; /* rad per tick */
    const float w_min = TWO_PI_F * k->notch_width_hz * k->ts_s;
    float x = raw;
    for (unsigned i = 0; i < HD_CTRL_NOTCH_MAX; i++) {
        if ((k->notch_mask & (1u << i)) == 0u) {
            continue;
        }
        hd_ctrl_sos_t *b = &c->notch[i];
        hd_ctrl_sos_state_t *st = &c->notch_state[i];
        if (!notch_tune(b, (float)(i + 1u) * w_motor, c->plan->notch_r, w_min)) {
            sos_pass(b);
            biquad_prime(b, st, x);
            continue;
        }
        if (prime) {
            biquad_prime(b, st, x);
        }
        x = biquad_step(b, st, x);
    }
    return x;
}

/* The notches and the low-pass run every tick the raw torque is usable
 * while the feedback uses them (the feedback source changes only with a new
 * configuration, which restarts them: hd_ctrl_start). */
static void lowpass_update(hd_ctrl_t *c, const hd_ctrl_input_t *in)
{
    const hd_ctrl_plan_t *p = c->plan;
    const hd_ctrl_config_t *k = &p->cfg;
    const bool used = k->feedback == HD_CTRL_FB_LOWPASS ||
                      (k->feedback == HD_CTRL_FB_RAW && k->notch_mask != 0u);
    if (!used || !in->torque_valid || !finite_f(in->torque_raw_nm) ||
        !finite_f(in->velocity_rad_s)) {
        return;
    }
    const bool prime = !c->lowpass_primed;
    const float x = notches(c, in->torque_raw_nm, in->velocity_rad_s, prime);
    c->raw_notched_nm = x;
    if (prime) {
        c->lowpass_nm = x;
        for (unsigned i = 0; i < HD_CTRL_BIQUAD_MAX; i++) {
            biquad_prime(&p->butter[i], &c->butter[i], x);
        }
        c->lowpass_primed = true;
        return;
    }
    if (k->lowpass_order == 1u) {
        c->lowpass_nm += p->lowpass_alpha * (x - c->lowpass_nm);
    } else {
        float y = biquad_step(&p->butter[0], &c->butter[0], x);
        if (k->lowpass_order == 4u) {
            y = biquad_step(&p->butter[1], &c->butter[1], y);
        }
        c->lowpass_nm = y;
    }
}

/* HD_CTRL_FB_NARROW's feedback (hd_ctrl.h): every tick the torque is usable
 * while the feedback uses it. */
static void narrow_update(hd_ctrl_t *c, const hd_ctrl_input_t *in)
{
    const hd_ctrl_plan_t *p = c->plan;
    const hd_ctrl_config_t *k = &p->cfg;
    c->narrow_ok = false;
    if (k->feedback != HD_CTRL_FB_NARROW || !in->torque_valid ||
        !finite_f(in->torque_raw_nm) || !finite_f(in->torque_filtered_nm) ||
        !finite_f(in->velocity_rad_s)) {
        return;
    }
    const float v = in->velocity_rad_s < 0.0f ? -in->velocity_rad_s : in->velocity_rad_s;
    const bool angle = in->motor_angle_valid && finite_f(in->motor_angle_rad);
    const float m = angle ? clampf((float)p->artifact_k_min * k->gear_ratio * v * p->narrow_inv_rad_s - 1.0f,
                                   0.0f, 1.0f)
                          : 0.0f;
    const float a = in->torque_raw_nm - in->torque_filtered_nm;
    const float a_hat = hd_artifact_step(&c->artifact, a, angle ? in->motor_angle_rad : 0.0f, m);
    c->narrow_nm = in->torque_filtered_nm + m * (a - a_hat);
    c->narrow_ok = true;
}

/* The feedback torque, or false when the selected source is unusable. */
static bool feedback_nm(const hd_ctrl_t *c, const hd_ctrl_input_t *in, float *fb)
{
    switch ((hd_ctrl_feedback_t)c->plan->cfg.feedback) {
    case HD_CTRL_FB_FILTERED:
        *fb = in->torque_filtered_nm;
        break;
    case HD_CTRL_FB_RAW:
        *fb = c->plan->cfg.notch_mask != 0u ? c->raw_notched_nm : in->torque_raw_nm;
        if (c->plan->cfg.notch_mask != 0u && !c->lowpass_primed) {
            return false;
        }
        break;
    case HD_CTRL_FB_NARROW:
        *fb = c->narrow_nm;
        if (!c->narrow_ok) {
            return false;
        }
        break;
    case HD_CTRL_FB_LOWPASS:
        *fb = c->lowpass_nm;
        if (!c->lowpass_primed) {
            return false;
        }
        break;
    default:
        *fb = 0.0f;
        return true;
    }
    return in->torque_valid && finite_f(*fb);
}

/* The mode that can run safely with these inputs; *fb the feedback torque
 * when the mode runs the torque loop. */
static hd_ctrl_mode_t pick_mode(const hd_ctrl_t *c, const hd_ctrl_setpoint_t *sp,
                                const hd_ctrl_input_t *in, uint8_t *limits, float *fb)
{
    if (sp->mode == HD_CTRL_STOP) {
        return HD_CTRL_STOP;
    }
    hd_ctrl_mode_t m = hd_ctrl_setpoint_valid(sp) ? sp->mode : HD_CTRL_DAMP;
    if (!finite_f(in->velocity_rad_s) || !finite_f(in->angle_rad)) {
        m = HD_CTRL_STOP;
    } else if (uses_torque_loop(m) && !feedback_nm(c, in, fb)) {
        m = HD_CTRL_DAMP;
    }
    if (m != sp->mode) {
        *limits |= HD_CTRL_LIM_FALLBACK;
    }
    return m;
}

/* ODrive's velocity-limited torque: the torque may not push the speed
 * beyond +-v_lim; beyond it, it must pull back at vel_gain. */
static float velocity_limited(const hd_ctrl_config_t *k, float tau, float v, uint8_t *limits)
{
    const float hi = k->velocity_gain_nm_s_rad * (k->velocity_limit_rad_s - v);
    const float lo = k->velocity_gain_nm_s_rad * (-k->velocity_limit_rad_s - v);
    if (tau > hi || tau < lo) {
        *limits |= HD_CTRL_LIM_VELOCITY;
        return tau > hi ? hi : lo;
    }
    return tau;
}

static float torque_reference(const hd_ctrl_config_t *k, hd_ctrl_mode_t m,
                              const hd_ctrl_setpoint_t *sp, const hd_ctrl_input_t *in,
                              uint8_t *limits)
{
    const float q = in->angle_rad, v = in->velocity_rad_s;
    float tau = 0.0f;
    if (m == HD_CTRL_DAMP) {
        tau = -k->damp_nm_s_rad * v;
    } else if (m == HD_CTRL_TORQUE) {
        tau = velocity_limited(k, sp->torque_nm, v, limits);
    } else if (m == HD_CTRL_IMPEDANCE) {
        tau = sp->kp_nm_rad * (sp->position_rad - q) + sp->kd_nm_s_rad * (sp->velocity_rad_s - v) +
              sp->torque_nm;
    }
    if (tau > k->torque_limit_nm || tau < -k->torque_limit_nm) {
        tau = clampf(tau, -k->torque_limit_nm, k->torque_limit_nm);
        *limits |= HD_CTRL_LIM_TORQUE;
    }
    /* Outside the window, no torque that pushes further out. */
    if ((q > k->position_max_rad && tau > 0.0f) || (q < k->position_min_rad && tau < 0.0f)) {
        tau = 0.0f;
        *limits |= HD_CTRL_LIM_POSITION;
    }
    return tau;
}

/* sqrt(x) for x in [0, 1] without libm (control/ has none): x is scaled by
 * 16 into [1/16, 1] (sqrt by 4; at most 20 times, below 16^-20 the root is
 * taken as 0), then Newton from (1 + x) / 2, which lies above the root and
 * converges from above: 5 steps reach float precision on [1/16, 1]. */
static float sqrt_unit(float x)
{
    if (!(x > 0.0f)) {
        return 0.0f;
    }
    float scale = 1.0f;
    for (unsigned k = 0; k < 20u && x < 0.0625f; k++) {
        x *= 16.0f;
        scale *= 0.25f;
    }
    if (x < 0.0625f) {
        return 0.0f;
    }
    float y = 0.5f * (1.0f + x);
    for (unsigned k = 0; k < 5u; k++) {
        y = 0.5f * (y + x / y);
    }
    return scale * y;
}

/* The integral's gain this tick.  Under an impedance with a spring the
 * integral closes a loop around the rendered mass-spring: the torque error it
 * integrates is mostly the torque that moves the motor's inertia with the
 * output, and an integral whose corner is not well below the mass-spring's
 * frequency sqrt(kp / J) makes the motor's friction stick and slip: the pushed
 * output hunts (docs/results/control.md, "Rendered stiffness").  The
 * frequency scales with sqrt(kp) whatever J is, so the gain does:
 * ki_t min(1, sqrt(kp / integral_stiffness_nm_rad)).  Without a spring (kp 0,
 * a pure damper) nothing oscillates and the full ki_t compensates the
 * friction. */
static float integral_gain_per_s(const hd_ctrl_config_t *k, hd_ctrl_mode_t m,
                                 const hd_ctrl_setpoint_t *sp)
{
    if (m != HD_CTRL_IMPEDANCE || !(sp->kp_nm_rad > 0.0f) ||
        sp->kp_nm_rad >= k->integral_stiffness_nm_rad) {
        return k->torque_ki_per_s;
    }
    return k->torque_ki_per_s * sqrt_unit(sp->kp_nm_rad / k->integral_stiffness_nm_rad);
}

/* The friction's compensation: in the direction the output moves
 * (friction_nm), and at rest in the direction the setpoint torque moves
 * (friction_rest_nm): with the output still the motor moves only by the
 * flexspline's windup, toward more torque when more is asked; faded out as
 * the speed reaches v_eps, where the first term has the motor's direction. */
static float friction_feedforward(const hd_ctrl_config_t *k, float v, float rate_nm_s)
{
    const float s = clampf(v / k->friction_velocity_rad_s, -1.0f, 1.0f);
    float u = k->friction_nm * s;
    if (k->friction_rest_nm > 0.0f) { /* off by default: no division in the tick */
        const float rest = 1.0f - (s < 0.0f ? -s : s);
        u += k->friction_rest_nm * rest * clampf(rate_nm_s / k->friction_rate_nm_s, -1.0f, 1.0f);
    }
    return u;
}

/* PI with the setpoint fed forward; the integral moves only while the
 * command is not saturated in the error's direction. */
static float torque_loop(hd_ctrl_t *c, float tau_ref, float fb, float v, float sp_rate,
                         float ki_per_s)
{
    const hd_ctrl_config_t *k = &c->plan->cfg;
    const float e = tau_ref - fb;
    /* the feedback's rate, on the measurement only (a setpoint step kicks nothing) */
    const float rate = c->fb_primed ? (fb - c->fb_prev_nm) / k->ts_s : 0.0f;
    c->fb_prev_nm = fb;
    c->fb_primed = true;
    const float u = k->torque_ff * tau_ref + k->torque_kp * e + c->integral_nm -
                    k->torque_kd_s * rate + friction_feedforward(k, v, sp_rate);
    const float u_max = k->current_limit_a * k->kt_nm_per_a * k->gear_ratio;
    const bool wind_up = (u >= u_max && e > 0.0f) || (u <= -u_max && e < 0.0f);
    if (!wind_up) {
        const float i_max = k->integral_limit_nm < u_max ? k->integral_limit_nm : u_max;
        c->integral_nm = clampf(c->integral_nm + ki_per_s * k->ts_s * e, -i_max, i_max);
    }
    return u;
}

static void stop(hd_ctrl_t *c, hd_ctrl_output_t *out)
{
    c->integral_nm = 0.0f;
    c->fb_primed = false;
    c->sp_torque_primed = false;
    out->enable = false;
    out->current_a = 0.0f;
    out->motor_torque_nm = 0.0f;
    out->torque_ref_nm = 0.0f;
    out->torque_fb_nm = 0.0f;
    out->mode = HD_CTRL_STOP;
}

void hd_ctrl_step(hd_ctrl_t *c, const hd_ctrl_setpoint_t *sp, const hd_ctrl_input_t *in,
                  hd_ctrl_output_t *out)
{
    if (out == NULL) {
        return;
    }
    /* field by field: a compound literal is a memset call on the M4F */
    out->enable = false;
    out->current_a = 0.0f;
    out->motor_torque_nm = 0.0f;
    out->torque_ref_nm = 0.0f;
    out->torque_fb_nm = 0.0f;
    out->limits = 0u;
    out->mode = HD_CTRL_STOP;
    if (c == NULL || sp == NULL || in == NULL) {
        out->mode = HD_CTRL_STOP;
        return;
    }
    lowpass_update(c, in);
    narrow_update(c, in);
    float fb = 0.0f;
    const hd_ctrl_mode_t m = pick_mode(c, sp, in, &out->limits, &fb);
    if (m == HD_CTRL_STOP) {
        stop(c, out);
        return;
    }
    const hd_ctrl_config_t *k = &c->plan->cfg;
    const float tau_ref = torque_reference(k, m, sp, in, &out->limits);
    /* the setpoint torque's rate: TORQUE's torque, IMPEDANCE's feed-forward;
     * none in the other modes, and none across a refused (non-finite) one */
    const bool rated = (m == HD_CTRL_TORQUE || m == HD_CTRL_IMPEDANCE) && finite_f(sp->torque_nm);
    const float sp_rate = k->friction_rest_nm > 0.0f && c->sp_torque_primed && rated
                              ? (sp->torque_nm - c->sp_torque_prev_nm) / k->ts_s
                              : 0.0f;
    c->sp_torque_prev_nm = rated ? sp->torque_nm : 0.0f;
    c->sp_torque_primed = rated;
    float u;
    if (!uses_torque_loop(m) || k->feedback == HD_CTRL_FB_NONE) {
        c->integral_nm = 0.0f;
        c->fb_primed = false;
        u = m == HD_CTRL_DAMP ? tau_ref
                               : tau_ref + friction_feedforward(k, in->velocity_rad_s, sp_rate);
    } else {
        out->torque_fb_nm = fb; /* pick_mode's: the mode runs the loop, so it was read */
        u = torque_loop(c, tau_ref, fb, in->velocity_rad_s, sp_rate,
                        integral_gain_per_s(k, m, sp));
    }
    float i = u / (k->gear_ratio * k->kt_nm_per_a);
    if (!finite_f(i)) {
        hd_ctrl_reset(c);
        stop(c, out);
        out->limits |= HD_CTRL_LIM_NONFINITE;
        return;
    }
    if (i > k->current_limit_a || i < -k->current_limit_a) {
        i = clampf(i, -k->current_limit_a, k->current_limit_a);
        out->limits |= HD_CTRL_LIM_CURRENT;
    }
    out->enable = true;
    out->current_a = i;
    out->motor_torque_nm = i * k->kt_nm_per_a;
    out->torque_ref_nm = tau_ref;
    out->mode = m;
}

const char *hd_ctrl_mode_name(int mode)
{
    static const char *const names[HD_CTRL_MODE_COUNT] = {"STOP", "DAMP", "TORQUE", "IMPEDANCE",
                                                          "ZERO_TORQUE"};
    return mode >= 0 && mode < HD_CTRL_MODE_COUNT ? names[mode] : "unknown";
}
