/*
 * hd_ctrl (control/) against closed forms and properties.
 *
 * Torque loop: the plant is a first-order lag of time constant T between
 * the joint torque the drive is asked for (u = N kt i) and the measured
 * torque, integrated exactly over each tick (zero-order hold).  With the PI
 * zero placed on the plant's pole (ki = kp / T) and no feed-forward the
 * open loop is kp / (s T), so the closed loop is first order:
 *     tau(t) / tau_d = 1 - exp(-t kp / T)
 * The controller's one-tick sampling delays the response by about half a
 * tick; we allow 2 % of the step for that (ts kp / T = 0.1 here).
 */
#include <math.h>
#include <stdio.h>
#include <stdlib.h>
#include <string.h>

#include "hd_ctrl.h"
#include "unity.h"

#define TS 1e-3
#define PI_D 3.14159265358979323846

void setUp(void) {}
void tearDown(void) {}

typedef struct {
    double tau_nm;   /* the plant's output torque */
    double lag_s;    /* T */
    double gain;     /* torque per N m asked for */
} lag_plant_t;

/* One tick of the plant under the drive's command (zero-order hold). */
static void plant_step(lag_plant_t *p, const hd_ctrl_config_t *k, const hd_ctrl_output_t *o)
{
    const double asked = (double)o->current_a * (double)k->kt_nm_per_a * (double)k->gear_ratio;
    const double a = exp(-TS / p->lag_s);
    p->tau_nm = a * p->tau_nm + (1.0 - a) * p->gain * asked;
}

static hd_ctrl_input_t input_of(double tau_nm, double q, double v)
{
    /* The raw torque is deliberately wrong by 5 N m: a loop that fed back
     * the wrong source would settle 5 N m off. */
    return (hd_ctrl_input_t){.torque_filtered_nm = (float)tau_nm,
                             .torque_raw_nm = (float)tau_nm + 5.0f,
                             .torque_valid = true,
                             .angle_rad = (float)q,
                             .velocity_rad_s = (float)v};
}

static void loop_config(hd_ctrl_config_t *k, double kp, double lag_s)
{
    hd_ctrl_config_default(k);
    k->torque_kp = (float)kp;
    k->torque_ki_per_s = (float)(kp / lag_s);
    k->torque_ff = 0.0f;
    k->integral_limit_nm = 1e4f; /* without feed-forward the integral carries the setpoint */
    k->integral_stiffness_nm_rad = 1.0f; /* the full ki at every kp: these loops have no spring */
}

static void test_config_check(void)
{
    hd_ctrl_config_t k;
    hd_ctrl_t c;
    hd_ctrl_plan_t plan;
    hd_ctrl_config_default(&k);
    TEST_ASSERT_EQUAL_INT(HD_CTRL_OK, hd_ctrl_init(&c, &plan, &k));
    const hd_ctrl_config_t good = k;
    float *fields[] = {&k.ts_s, &k.gear_ratio, &k.kt_nm_per_a, &k.torque_kp, &k.torque_ki_per_s,
                       &k.torque_ff, &k.torque_kd_s, &k.integral_limit_nm, &k.integral_stiffness_nm_rad, &k.lowpass_hz, &k.friction_nm, &k.friction_velocity_rad_s,
                       &k.friction_rest_nm, &k.friction_rate_nm_s,
                       &k.damp_nm_s_rad, &k.torque_limit_nm, &k.current_limit_a,
                       &k.velocity_limit_rad_s, &k.velocity_gain_nm_s_rad};
    const float bad[] = {NAN, INFINITY, -1.0f, 1e9f};
    for (size_t f = 0; f < sizeof fields / sizeof fields[0]; f++) {
        for (size_t b = 0; b < sizeof bad / sizeof bad[0]; b++) {
            k = good;
            *fields[f] = bad[b];
            TEST_ASSERT_EQUAL_INT(HD_CTRL_ERR_CONFIG, hd_ctrl_config_check(&k));
        }
    }
    k = good;
    k.position_min_rad = k.position_max_rad;
    TEST_ASSERT_EQUAL_INT(HD_CTRL_ERR_CONFIG, hd_ctrl_config_check(&k));
    k = good;
    k.feedback = HD_CTRL_FB_COUNT;
    TEST_ASSERT_EQUAL_INT(HD_CTRL_ERR_CONFIG, hd_ctrl_init(&c, &plan, &k));
    k = good;
    k.lowpass_hz = 500.0f; /* Nyquist at 1 kHz */
    TEST_ASSERT_EQUAL_INT(HD_CTRL_ERR_CONFIG, hd_ctrl_config_check(&k));
    TEST_ASSERT_EQUAL_INT(HD_CTRL_ERR_NULL, hd_ctrl_init(NULL, &plan, &good));
}

/* Step of the filtered-feedback loop against the first-order closed form. */
static void test_torque_step_first_order_closed_loop(void)
{
    const double kp = 2.0, lag = 0.02, step = 10.0, tau_cl = lag / kp;
    hd_ctrl_config_t k;
    hd_ctrl_t c;
    hd_ctrl_plan_t plan;
    loop_config(&k, kp, lag);
    TEST_ASSERT_EQUAL_INT(HD_CTRL_OK, hd_ctrl_init(&c, &plan, &k));
    lag_plant_t p = {.tau_nm = 0.0, .lag_s = lag, .gain = 1.0};
    const hd_ctrl_setpoint_t sp = {.mode = HD_CTRL_TORQUE, .torque_nm = (float)step};
    double worst = 0.0;
    for (int n = 1; n <= 200; n++) {
        hd_ctrl_output_t o;
        const hd_ctrl_input_t in = input_of(p.tau_nm, 0.0, 0.0);
        hd_ctrl_step(&c, &sp, &in, &o);
        TEST_ASSERT_EQUAL_INT(HD_CTRL_TORQUE, o.mode);
        plant_step(&p, &k, &o);
        const double expect = step * (1.0 - exp(-n * TS / tau_cl));
        worst = fmax(worst, fabs(p.tau_nm - expect));
    }
    printf("control: first-order closed loop, worst deviation %.4f N m of a %.0f N m step\n",
           worst, step);
    TEST_ASSERT_DOUBLE_WITHIN(0.02 * step, 0.0, worst);
    TEST_ASSERT_DOUBLE_WITHIN(1e-3, step, p.tau_nm); /* integral action: no offset */
}

/* Saturated for 2 s, then a reachable setpoint: with the conditional
 * integration the loop leaves saturation at once and settles like an
 * unsaturated step; a wound-up integral holds it off. */
static void test_antiwindup_recovers_like_a_fresh_step(void)
{
    const double kp = 2.0, lag = 0.02, tau_cl = lag / kp;
    hd_ctrl_config_t k;
    hd_ctrl_t c;
    hd_ctrl_plan_t plan;
    loop_config(&k, kp, lag);
    TEST_ASSERT_EQUAL_INT(HD_CTRL_OK, hd_ctrl_init(&c, &plan, &k));
    /* a weak drive (gain 0.5): u_max = 8 A * 0.06 * 100 = 48 gives 24 N m */
    lag_plant_t p = {.tau_nm = 0.0, .lag_s = lag, .gain = 0.5};
    hd_ctrl_setpoint_t sp = {.mode = HD_CTRL_TORQUE, .torque_nm = 40.0f};
    hd_ctrl_output_t o;
    for (int n = 0; n < 2000; n++) {
        const hd_ctrl_input_t in = input_of(p.tau_nm, 0.0, 0.0);
        hd_ctrl_step(&c, &sp, &in, &o);
        plant_step(&p, &k, &o);
    }
    TEST_ASSERT_TRUE(o.limits & HD_CTRL_LIM_CURRENT);
    TEST_ASSERT_DOUBLE_WITHIN(0.01, 24.0, p.tau_nm);
    sp.torque_nm = 10.0f;
    int settled = -1;
    for (int n = 1; n <= 500 && settled < 0; n++) {
        const hd_ctrl_input_t in = input_of(p.tau_nm, 0.0, 0.0);
        hd_ctrl_step(&c, &sp, &in, &o);
        plant_step(&p, &k, &o);
        if (fabs(p.tau_nm - 10.0) < 0.02 * 14.0) {
            settled = n;
        }
    }
    /* within 2 % of the 14 N m step: 3.9 tau_cl for a first-order loop */
    printf("control: after 2 s saturated, 2 %% settling in %d ms (first order: %.1f ms)\n",
           settled, 1e3 * tau_cl * log(50.0));
    TEST_ASSERT_TRUE(settled > 0);
    TEST_ASSERT_LESS_OR_EQUAL((int)(1.3 * tau_cl * log(50.0) / TS), settled);
}

/* The integral's bound: with the setpoint fed forward, a plant that loses
 * d N m (the drive train's friction) settles on the setpoint while d is
 * within integral_limit_nm (the integral holds d), and beyond it at the
 * proportional loop's error, closed form: tau = tau_d - (d - I_max) / (1 + kp). */
static void test_integral_bounded_by_its_limit(void)
{
    const double kp = 0.5, lag = 0.02, step = 10.0, limit = 4.0;
    const double losses[2] = {3.0, 6.0};
    for (int i = 0; i < 2; i++) {
        hd_ctrl_config_t k;
        hd_ctrl_t c;
        hd_ctrl_plan_t plan;
        loop_config(&k, kp, lag);
        k.torque_ff = 1.0f;
        k.integral_limit_nm = (float)limit;
        TEST_ASSERT_EQUAL_INT(HD_CTRL_OK, hd_ctrl_init(&c, &plan, &k));
        lag_plant_t p = {.tau_nm = 0.0, .lag_s = lag, .gain = 1.0};
        const hd_ctrl_setpoint_t sp = {.mode = HD_CTRL_TORQUE, .torque_nm = (float)step};
        for (int n = 0; n < 3000; n++) {
            hd_ctrl_output_t o;
            const hd_ctrl_input_t in = input_of(p.tau_nm, 0.0, 0.0);
            hd_ctrl_step(&c, &sp, &in, &o);
            plant_step(&p, &k, &o);
            p.tau_nm -= (1.0 - exp(-TS / lag)) * losses[i]; /* the loss, through the lag */
        }
        const double expect = step - fmax(0.0, losses[i] - limit) / (1.0 + kp);
        printf("control: loss %.0f N m, integral limit %.0f N m: settles at %.4f N m "
               "(closed form %.4f)\n", losses[i], limit, p.tau_nm, expect);
        TEST_ASSERT_DOUBLE_WITHIN(1e-3, expect, p.tau_nm);
        TEST_ASSERT_DOUBLE_WITHIN(1e-4, fmin(losses[i], limit), (double)c.integral_nm);
    }
}

/* The rate term: -kd_t times the feedback's backward difference over a
 * tick, nothing on the first tick of the loop (no previous feedback) and
 * nothing from a setpoint step (it acts on the measurement only). */
static void test_rate_term_on_the_feedback(void)
{
    hd_ctrl_config_t k;
    hd_ctrl_t c;
    hd_ctrl_plan_t plan;
    hd_ctrl_config_default(&k);
    k.torque_kp = 0.5f, k.torque_ki_per_s = 0.0f, k.torque_ff = 0.0f, k.torque_kd_s = 2e-3f;
    TEST_ASSERT_EQUAL_INT(HD_CTRL_OK, hd_ctrl_init(&c, &plan, &k));
    const double nkt = (double)k.gear_ratio * (double)k.kt_nm_per_a, slope = 300.0; /* N m/s */
    hd_ctrl_setpoint_t sp = {.mode = HD_CTRL_TORQUE, .torque_nm = 0.0f};
    hd_ctrl_output_t o;
    for (int n = 0; n < 5; n++) {
        if (n == 3) {
            sp.torque_nm = 20.0f; /* a step of the setpoint: no kick */
        }
        const double fb = 1.0 + slope * TS * n;
        const hd_ctrl_input_t in = input_of(fb, 0.0, 0.0);
        hd_ctrl_step(&c, &sp, &in, &o);
        const double expect = (double)k.torque_kp * ((double)sp.torque_nm - fb) -
                              (n == 0 ? 0.0 : (double)k.torque_kd_s * slope);
        TEST_ASSERT_DOUBLE_WITHIN(1e-4, expect, (double)o.current_a * nkt);
    }
    sp.mode = HD_CTRL_DAMP; /* out of the loop: the next loop tick starts unprimed */
    hd_ctrl_input_t in = input_of(100.0, 0.0, 0.0);
    hd_ctrl_step(&c, &sp, &in, &o);
    sp.mode = HD_CTRL_TORQUE, sp.torque_nm = 0.0f;
    in = input_of(0.0, 0.0, 0.0);
    hd_ctrl_step(&c, &sp, &in, &o);
    TEST_ASSERT_DOUBLE_WITHIN(1e-6, 0.0, (double)o.current_a);
}

/* The friction compensation at rest, open loop (feedback none: u = tau_ref +
 * compensation) against its closed form F_r sat(r / r_eps) max(0, 1 - |v| /
 * v_eps), r the setpoint torque's rate over one tick: the sign of a ramp, its
 * share below r_eps, the fade with the speed, nothing on a held setpoint or
 * the first tick, and no rate across a non-finite setpoint (its DAMP tick)
 * or a STOP. */
static float rest_current(hd_ctrl_t *c, float torque_nm, float v)
{
    const hd_ctrl_setpoint_t sp = {.mode = HD_CTRL_TORQUE, .torque_nm = torque_nm};
    const hd_ctrl_input_t in = input_of(0.0, 0.0, v);
    hd_ctrl_output_t o;
    hd_ctrl_step(c, &sp, &in, &o);
    return o.current_a;
}

static void test_friction_at_rest_follows_the_setpoint_rate(void)
{
    hd_ctrl_config_t k;
    hd_ctrl_t c;
    hd_ctrl_plan_t plan;
    hd_ctrl_config_default(&k);
    k.feedback = HD_CTRL_FB_NONE;
    k.friction_rest_nm = 2.0f, k.friction_rate_nm_s = 1000.0f, k.friction_velocity_rad_s = 0.05f;
    TEST_ASSERT_EQUAL_INT(HD_CTRL_OK, hd_ctrl_init(&c, &plan, &k));
    const double nkt = (double)k.gear_ratio * (double)k.kt_nm_per_a;
    const struct {
        float torque, v;
        double comp; /* the compensation expected, joint N m */
    } rows[] = {
        {10.0f, 0.0f, 0.0},     /* first tick: no rate yet */
        {12.0f, 0.0f, 2.0},     /* 2000 N m/s up, at rest: +F_r */
        {12.0f, 0.0f, 0.0},     /* held: none */
        {10.0f, 0.0f, -2.0},    /* down */
        {10.5f, 0.0f, 1.0},     /* 500 N m/s: half of it */
        {12.5f, 0.025f, 1.0},   /* half v_eps: faded to half */
        {14.5f, -0.025f, 1.0},  /* whichever way the output turns */
        {16.5f, 0.05f, 0.0},    /* at v_eps: gone */
        {18.5f, 3.0f, 0.0},
    };
    for (size_t i = 0; i < sizeof rows / sizeof rows[0]; i++) {
        const float i_a = rest_current(&c, rows[i].torque, rows[i].v);
        TEST_ASSERT_DOUBLE_WITHIN(2e-5, ((double)rows[i].torque + rows[i].comp) / nkt, (double)i_a);
    }
    (void)rest_current(&c, NAN, 0.0f);                       /* DAMP: refused setpoint */
    TEST_ASSERT_DOUBLE_WITHIN(2e-5, 12.0 / nkt, (double)rest_current(&c, 12.0f, 0.0f));
    hd_ctrl_setpoint_t zt = {.mode = HD_CTRL_ZERO_TORQUE, .torque_nm = 20.0f}; /* torque unused */
    hd_ctrl_output_t oz;
    const hd_ctrl_input_t rest_in = input_of(0.0, 0.0, 0.0);
    hd_ctrl_step(&c, &zt, &rest_in, &oz);
    zt.torque_nm = 30.0f;
    hd_ctrl_step(&c, &zt, &rest_in, &oz);
    TEST_ASSERT_DOUBLE_WITHIN(2e-5, 0.0, (double)oz.current_a);
    TEST_ASSERT_DOUBLE_WITHIN(2e-5, 12.0 / nkt, (double)rest_current(&c, 12.0f, 0.0f));
    const hd_ctrl_setpoint_t stop = {.mode = HD_CTRL_STOP};
    const hd_ctrl_input_t in = input_of(0.0, 0.0, 0.0);
    hd_ctrl_output_t o;
    hd_ctrl_step(&c, &stop, &in, &o);
    TEST_ASSERT_DOUBLE_WITHIN(2e-5, 5.0 / nkt, (double)rest_current(&c, 5.0f, 0.0f));
    /* in the loop too, beside the PI (kp 0.5, no integral, no feed-forward) */
    k.feedback = HD_CTRL_FB_FILTERED;
    k.torque_kp = 0.5f, k.torque_ki_per_s = 0.0f, k.torque_ff = 0.0f, k.torque_kd_s = 0.0f;
    TEST_ASSERT_EQUAL_INT(HD_CTRL_OK, hd_ctrl_init(&c, &plan, &k));
    (void)rest_current(&c, 10.0f, 0.0f);
    TEST_ASSERT_DOUBLE_WITHIN(2e-5, (0.5 * 8.0 - 2.0) / nkt, (double)rest_current(&c, 8.0f, 0.0f));
}

/* Impedance through the torque loop against a fixed output: the torque the
 * plant settles at is kp (q_d - q) + kd (v_d - v) + tau_ff; the slope over
 * q is the rendered stiffness. */
static void test_impedance_renders_kp(void)
{
    const double kp_t = 2.0, lag = 0.02;
    const double kp = 150.0, kd = 2.0, qd = 0.3, vd = 0.5, ff = 1.5;
    hd_ctrl_config_t k;
    hd_ctrl_t c;
    hd_ctrl_plan_t plan;
    loop_config(&k, kp_t, lag);
    const double qs[2] = {0.25, 0.4};
    double tau[2];
    for (int j = 0; j < 2; j++) {
        TEST_ASSERT_EQUAL_INT(HD_CTRL_OK, hd_ctrl_init(&c, &plan, &k));
        lag_plant_t p = {.tau_nm = 0.0, .lag_s = lag, .gain = 1.0};
        const hd_ctrl_setpoint_t sp = {.mode = HD_CTRL_IMPEDANCE, .torque_nm = (float)ff,
                                       .position_rad = (float)qd, .velocity_rad_s = (float)vd,
                                       .kp_nm_rad = (float)kp, .kd_nm_s_rad = (float)kd};
        for (int n = 0; n < 500; n++) {
            hd_ctrl_output_t o;
            const hd_ctrl_input_t in = input_of(p.tau_nm, qs[j], 0.0);
            hd_ctrl_step(&c, &sp, &in, &o);
            plant_step(&p, &k, &o);
        }
        tau[j] = p.tau_nm;
        TEST_ASSERT_DOUBLE_WITHIN(1e-3, kp * (qd - qs[j]) + kd * vd + ff, tau[j]);
    }
    const double rendered = -(tau[1] - tau[0]) / (qs[1] - qs[0]);
    printf("control: rendered stiffness %.3f N m/rad for kp %.0f\n", rendered, kp);
    TEST_ASSERT_DOUBLE_WITHIN(1e-3 * kp, kp, rendered);
}

static hd_ctrl_output_t one_step(const hd_ctrl_config_t *k, hd_ctrl_setpoint_t sp,
                                 hd_ctrl_input_t in)
{
    hd_ctrl_t c;
    hd_ctrl_plan_t plan;
    hd_ctrl_output_t o;
    TEST_ASSERT_EQUAL_INT(HD_CTRL_OK, hd_ctrl_init(&c, &plan, k));
    hd_ctrl_step(&c, &sp, &in, &o);
    return o;
}

static void test_modes_and_fallbacks(void)
{
    hd_ctrl_config_t k;
    hd_ctrl_config_default(&k);
    const float amps_per_nm = 1.0f / (k.gear_ratio * k.kt_nm_per_a);
    const hd_ctrl_input_t in = input_of(0.0, 0.1, 0.8);
    hd_ctrl_output_t o = one_step(&k, (hd_ctrl_setpoint_t){.mode = HD_CTRL_STOP}, in);
    TEST_ASSERT_FALSE(o.enable);
    TEST_ASSERT_EQUAL_FLOAT(0.0f, o.current_a);
    /* DAMP: -damp v, open loop */
    o = one_step(&k, (hd_ctrl_setpoint_t){.mode = HD_CTRL_DAMP}, in);
    TEST_ASSERT_TRUE(o.enable);
    TEST_ASSERT_FLOAT_WITHIN(1e-6, -k.damp_nm_s_rad * 0.8f * amps_per_nm, o.current_a);
    /* an invalid setpoint (unknown mode, NaN, kp out of range) runs DAMP */
    const hd_ctrl_setpoint_t bad[] = {
        {.mode = (hd_ctrl_mode_t)7},
        {.mode = HD_CTRL_TORQUE, .torque_nm = NAN},
        {.mode = HD_CTRL_IMPEDANCE, .kp_nm_rad = HD_CTRL_KP_MAX_NM_RAD * 2.0f},
        {.mode = HD_CTRL_IMPEDANCE, .kd_nm_s_rad = -1.0f},
        {.mode = HD_CTRL_IMPEDANCE, .position_rad = INFINITY},
    };
    for (size_t j = 0; j < sizeof bad / sizeof bad[0]; j++) {
        TEST_ASSERT_FALSE(hd_ctrl_setpoint_valid(&bad[j]));
        o = one_step(&k, bad[j], in);
        TEST_ASSERT_EQUAL_INT(HD_CTRL_DAMP, o.mode);
        TEST_ASSERT_TRUE(o.limits & HD_CTRL_LIM_FALLBACK);
    }
    /* the gauge unusable: the torque loop cannot run, DAMP ... */
    hd_ctrl_input_t nogauge = in;
    nogauge.torque_valid = false;
    const hd_ctrl_setpoint_t sp = {.mode = HD_CTRL_TORQUE, .torque_nm = 3.0f};
    TEST_ASSERT_EQUAL_INT(HD_CTRL_DAMP, one_step(&k, sp, nogauge).mode);
    nogauge.torque_valid = true;
    nogauge.torque_filtered_nm = NAN;
    TEST_ASSERT_EQUAL_INT(HD_CTRL_DAMP, one_step(&k, sp, nogauge).mode);
    /* ... but open loop needs no gauge: tau / (N kt) */
    k.feedback = HD_CTRL_FB_NONE;
    o = one_step(&k, sp, nogauge);
    TEST_ASSERT_EQUAL_INT(HD_CTRL_TORQUE, o.mode);
    TEST_ASSERT_FLOAT_WITHIN(1e-6, 3.0f * amps_per_nm, o.current_a);
    /* no velocity: nothing safe to damp with, STOP */
    hd_ctrl_input_t novel = in;
    novel.velocity_rad_s = NAN;
    o = one_step(&k, sp, novel);
    TEST_ASSERT_EQUAL_INT(HD_CTRL_STOP, o.mode);
    TEST_ASSERT_FALSE(o.enable);
}

static void test_velocity_and_position_limits(void)
{
    hd_ctrl_config_t k;
    hd_ctrl_config_default(&k);
    k.feedback = HD_CTRL_FB_NONE;
    /* beyond the velocity limit a forward torque becomes a pull-back of
     * vel_gain (v_lim - v) */
    const float v = k.velocity_limit_rad_s + 0.5f;
    hd_ctrl_output_t o = one_step(&k, (hd_ctrl_setpoint_t){.mode = HD_CTRL_TORQUE, .torque_nm = 5.0f},
                                  input_of(0.0, 0.0, v));
    TEST_ASSERT_TRUE(o.limits & HD_CTRL_LIM_VELOCITY);
    TEST_ASSERT_FLOAT_WITHIN(1e-4, -0.5f * k.velocity_gain_nm_s_rad, o.torque_ref_nm);
    /* just below it, the torque passes unchanged */
    o = one_step(&k, (hd_ctrl_setpoint_t){.mode = HD_CTRL_TORQUE, .torque_nm = 5.0f},
                 input_of(0.0, 0.0, k.velocity_limit_rad_s - 0.5f));
    TEST_ASSERT_EQUAL_FLOAT(5.0f, o.torque_ref_nm);
    /* beyond the window: outward torque cut, inward torque kept */
    const float q = k.position_max_rad + 0.1f;
    o = one_step(&k, (hd_ctrl_setpoint_t){.mode = HD_CTRL_TORQUE, .torque_nm = 5.0f},
                 input_of(0.0, q, 0.0));
    TEST_ASSERT_TRUE(o.limits & HD_CTRL_LIM_POSITION);
    TEST_ASSERT_EQUAL_FLOAT(0.0f, o.current_a);
    o = one_step(&k, (hd_ctrl_setpoint_t){.mode = HD_CTRL_TORQUE, .torque_nm = -5.0f},
                 input_of(0.0, q, 0.0));
    TEST_ASSERT_EQUAL_FLOAT(-5.0f, o.torque_ref_nm);
    /* the torque limit */
    o = one_step(&k, (hd_ctrl_setpoint_t){.mode = HD_CTRL_TORQUE, .torque_nm = 1e6f},
                 input_of(0.0, 0.0, 0.0));
    TEST_ASSERT_TRUE(o.limits & HD_CTRL_LIM_TORQUE);
    TEST_ASSERT_EQUAL_FLOAT(k.torque_limit_nm, o.torque_ref_nm);
}

/* xorshift64*: a reproducible stream for the property test. */
static uint64_t rng_state = 0x9E3779B97F4A7C15ull;
static uint64_t rng_next(void)
{
    rng_state ^= rng_state >> 12;
    rng_state ^= rng_state << 25;
    rng_state ^= rng_state >> 27;
    return rng_state * 2685821657736338717ull;
}

/* Any float: specials, huge, tiny and ordinary values. */
static float any_float(void)
{
    const uint64_t r = rng_next();
    switch (r % 8u) {
    case 0: return NAN;
    case 1: return (r & 256u) ? INFINITY : -INFINITY;
    case 2: return (r & 256u) ? 3.0e38f : -3.0e38f;
    case 3: {
        const uint32_t bits = (uint32_t)(r >> 32);
        float f;
        memcpy(&f, &bits, sizeof f);
        return f;
    }
    default: return (float)((double)(int64_t)(r >> 11) / 9007199254740992.0 * 200.0 - 100.0);
    }
}

static float unit(void)
{
    return (float)((double)(rng_next() >> 11) / 9007199254740992.0);
}

/* 200 random in-range configurations x 1000 steps of random setpoints and
 * inputs: the current never leaves +-limit, never is non-finite, STOP never
 * enables the drive, and tau_ref never leaves +-torque limit. */
static void test_property_limits_hold_for_any_input(void)
{
    long steps = 0, clamped = 0;
    for (int cfg_n = 0; cfg_n < 200; cfg_n++) {
        hd_ctrl_config_t k;
        hd_ctrl_config_default(&k);
        k.feedback = (hd_ctrl_feedback_t)(rng_next() % HD_CTRL_FB_COUNT);
        k.torque_kp = unit() * HD_CTRL_TORQUE_GAIN_MAX;
        k.torque_ki_per_s = unit() * HD_CTRL_KI_MAX_PER_S;
        k.torque_ff = unit();
        k.friction_nm = unit() * 1000.0f;
        k.friction_rest_nm = unit() * 1000.0f;
        k.friction_rate_nm_s = 1e-3f + unit() * 10.0f;
        k.damp_nm_s_rad = unit() * 1000.0f;
        k.current_limit_a = 0.01f + unit() * 50.0f;
        k.torque_limit_nm = 0.01f + unit() * 100.0f;
        k.velocity_gain_nm_s_rad = unit() * 1e4f;
        hd_ctrl_t c;
        hd_ctrl_plan_t plan;
        TEST_ASSERT_EQUAL_INT(HD_CTRL_OK, hd_ctrl_init(&c, &plan, &k));
        for (int n = 0; n < 1000; n++, steps++) {
            const hd_ctrl_setpoint_t sp = {
                .mode = (hd_ctrl_mode_t)(rng_next() % 7u), .torque_nm = any_float(),
                .position_rad = any_float(), .velocity_rad_s = any_float(),
                .kp_nm_rad = (rng_next() & 1u) ? unit() * HD_CTRL_KP_MAX_NM_RAD : any_float(),
                .kd_nm_s_rad = (rng_next() & 1u) ? unit() * HD_CTRL_KD_MAX_NM_S_RAD : any_float()};
            const hd_ctrl_input_t in = {.torque_filtered_nm = any_float(),
                                        .torque_raw_nm = any_float(),
                                        .torque_valid = (rng_next() & 3u) != 0u,
                                        .angle_rad = any_float(),
                                        .velocity_rad_s = any_float()};
            hd_ctrl_output_t o;
            hd_ctrl_step(&c, &sp, &in, &o);
            TEST_ASSERT_TRUE(isfinite(o.current_a));
            TEST_ASSERT_TRUE(fabsf(o.current_a) <= k.current_limit_a);
            TEST_ASSERT_TRUE(fabsf(o.torque_ref_nm) <= k.torque_limit_nm);
            TEST_ASSERT_TRUE(isfinite(c.integral_nm));
            if (sp.mode == HD_CTRL_STOP || o.mode == HD_CTRL_STOP) {
                TEST_ASSERT_FALSE(o.enable);
                TEST_ASSERT_EQUAL_FLOAT(0.0f, o.current_a);
            }
            clamped += (o.limits & HD_CTRL_LIM_CURRENT) != 0u;
        }
    }
    printf("control: %ld random steps, %ld at the current limit, none beyond\n", steps, clamped);
    TEST_ASSERT_GREATER_THAN(1000, clamped); /* the limit was exercised */
}

/* The feedback the law uses for a raw torque 10 + sin(w k) (filtered
 * deliberately wrong, so only the raw path can produce it): the amplitude of
 * the feedback's sine over ticks 2000..3999, by least squares on sin/cos. */
static double feedback_gain(const hd_ctrl_config_t *k, double w_rad_per_tick, double v_rad_s)
{
    hd_ctrl_t c;
    hd_ctrl_plan_t plan;
    TEST_ASSERT_EQUAL_INT(HD_CTRL_OK, hd_ctrl_init(&c, &plan, k));
    const hd_ctrl_setpoint_t sp = {.mode = HD_CTRL_TORQUE, .torque_nm = 10.0f};
    double ss = 0.0, cc = 0.0, ys = 0.0, yc = 0.0;
    for (int n = 0; n < 4000; n++) {
        hd_ctrl_input_t in = input_of(0.0, 0.0, v_rad_s);
        in.torque_raw_nm = (float)(10.0 + sin(w_rad_per_tick * n));
        hd_ctrl_output_t o;
        hd_ctrl_step(&c, &sp, &in, &o);
        TEST_ASSERT_EQUAL_INT(HD_CTRL_TORQUE, o.mode);
        if (n >= 2000) {
            const double si = sin(w_rad_per_tick * n), co = cos(w_rad_per_tick * n);
            const double y = (double)o.torque_fb_nm - 10.0;
            ss += si * si, cc += co * co, ys += y * si, yc += y * co;
        }
    }
    return hypot(ys / ss, yc / cc);
}

/* The Butterworth low-pass against its closed form: bilinear with the
 * corner pre-warped gives exactly |H| = 1/sqrt(2) at the corner for every
 * order, |H|^2 = 1 / (1 + (tan(w/2) / tan(wc/2))^(2n)) elsewhere. */
static void test_butterworth_feedback_closed_form(void)
{
    const double fc = 40.0, f[3] = {10.0, 40.0, 120.0};
    const int orders[2] = {2, 4};
    for (int o = 0; o < 2; o++) {
        hd_ctrl_config_t k;
        hd_ctrl_config_default(&k);
        k.feedback = HD_CTRL_FB_LOWPASS;
        k.lowpass_hz = (float)fc;
        k.lowpass_order = (uint8_t)orders[o];
        for (int i = 0; i < 3; i++) {
            const double w = 2.0 * PI_D * f[i] * TS;
            const double r = tan(w / 2.0) / tan(PI_D * fc * TS);
            const double expect = 1.0 / sqrt(1.0 + pow(r, 2.0 * orders[o]));
            const double got = feedback_gain(&k, w, 0.0);
            printf("control: Butterworth order %d, %.0f Hz corner, at %.0f Hz: gain %.5f "
                   "(closed form %.5f)\n", orders[o], fc, f[i], got, expect);
            TEST_ASSERT_DOUBLE_WITHIN(2e-3, expect, got);
        }
    }
}

/* The order notch: a sine at 2x the motor angle (N v ts rad per tick)
 * is removed, one at 3x passes (only orders 2 and 4 are notched), and at
 * standstill the notch passes everything (its frequency is 0). */
static void test_order_notch_tracks_the_speed(void)
{
    hd_ctrl_config_t k;
    hd_ctrl_config_default(&k);
    k.feedback = HD_CTRL_FB_RAW;
    k.notch_mask = (1u << 1) | (1u << 3);
    k.notch_width_hz = 5.0f;
    const double v = 1.5, w_motor = (double)k.gear_ratio * v * TS;
    const double at2 = feedback_gain(&k, 2.0 * w_motor, v);
    const double at4 = feedback_gain(&k, 4.0 * w_motor, -v);
    const double at3 = feedback_gain(&k, 3.0 * w_motor, v);
    const double still = feedback_gain(&k, 2.0 * w_motor, 0.0);
    printf("control: order notch at %.1f rad/s: gain at 2x %.5f, 4x %.5f, 3x %.4f; at "
           "standstill %.4f\n", v, at2, at4, at3, still);
    TEST_ASSERT_TRUE(at2 < 1e-2 && at4 < 1e-2);
    TEST_ASSERT_DOUBLE_WITHIN(0.1, 1.0, at3);
    TEST_ASSERT_DOUBLE_WITHIN(1e-4, 1.0, still);
}

/* The narrowed feedback (HD_CTRL_FB_NARROW) against its definition
 * filtered + m (a - a_hat): a 2x artifact locked to the motor angle at
 * 1.5 rad/s (a notch-free raw torque of 10 N m) is gone from the feedback
 * once the phasors converged (5 s, 16 time constants), while a torque tone
 * 3 Hz off the line passes; at a standstill (m = 0) and without a valid
 * motor angle the feedback is the filtered torque exactly; the corner is
 * checked. */
static void test_narrow_feedback_fades_with_motion(void)
{
    hd_ctrl_config_t k;
    hd_ctrl_config_default(&k);
    k.feedback = HD_CTRL_FB_NARROW;
    k.artifact_mask = 1u << 1;
    k.artifact_hz = 0.5f;
    hd_ctrl_t c;
    hd_ctrl_plan_t plan;
    TEST_ASSERT_EQUAL_INT(HD_CTRL_OK, hd_ctrl_init(&c, &plan, &k));
    const hd_ctrl_setpoint_t sp = {HD_CTRL_TORQUE, 10.0f, 0.0f, 0.0f, 0.0f, 0.0f};
    hd_ctrl_output_t o;
    const double v = 1.5, wm = (double)k.gear_ratio * v, f2 = 2.0 * wm / (2.0 * PI_D);
    double worst = 0.0, c_sum = 0.0, s_sum = 0.0;
    const int n = 8000;
    for (int i = 0; i < n; i++) {
        const double t = i * TS, th = fmod(wm * t, 2.0 * PI_D);
        const double art = 1.5 * sin(2.0 * th + 1.1);
        const double tone = i >= 5000 ? 0.5 * sin(2.0 * PI_D * (f2 + 3.0) * t) : 0.0;
        /* the filter's output: here it removes the artifact and half the tone */
        const hd_ctrl_input_t in = {(float)(10.0 + 0.5 * tone), (float)(10.0 + tone + art), true,
                                    0.0f, (float)v, (float)th, true};
        hd_ctrl_step(&c, &sp, &in, &o);
        if (i >= 4000 && i < 5000) {
            worst = fmax(worst, fabs((double)o.torque_fb_nm - 10.0));
        }
        if (i >= 6000) { /* 2 s: whole periods of f2 + 3 within 0.2 % */
            const double ph = 2.0 * PI_D * (f2 + 3.0) * t;
            c_sum += ((double)o.torque_fb_nm - 10.0) * cos(ph);
            s_sum += ((double)o.torque_fb_nm - 10.0) * sin(ph);
        }
    }
    const double tone_gain = 2.0 * hypot(c_sum, s_sum) / 2000.0 / 0.5;
    /* the tracker sees half the tone (a = raw - filtered) through a notch
     * 3 Hz off: 1 - 0.5 (1 - 3 / sqrt(9 + 0.25)) ~ 0.993 */
    printf("control: narrowed feedback at %.1f rad/s: artifact left %.4f N m, a tone 3 Hz off "
           "the line passes at %.3f\n", v, worst, tone_gain);
    TEST_ASSERT_TRUE(worst < 0.02);
    TEST_ASSERT_DOUBLE_WITHIN(0.03, 0.993, tone_gain);
    /* still: the filtered torque exactly; moving without a valid angle too */
    for (int still = 0; still < 2; still++) {
        const hd_ctrl_input_t in = {7.25f, 9.5f, true, 0.0f, still ? 0.0f : (float)v, 0.3f,
                                    still ? true : false};
        hd_ctrl_step(&c, &sp, &in, &o);
        TEST_ASSERT_EQUAL_FLOAT(7.25f, o.torque_fb_nm);
    }
    k.artifact_hz = 0.0f;
    TEST_ASSERT_EQUAL_INT(HD_CTRL_ERR_CONFIG, hd_ctrl_config_check(&k));
    k.artifact_hz = 51.0f;
    TEST_ASSERT_EQUAL_INT(HD_CTRL_ERR_CONFIG, hd_ctrl_config_check(&k));
}

/* The integral's schedule under IMPEDANCE: with the feedback and the angle
 * held, u grows each tick by exactly ki_eff ts e (the rate term is 0 after
 * the first tick), ki_eff = ki sqrt(kp / integral_stiffness) below it (libm's
 * sqrt in double as the reference), the full ki at and above it, at kp 0 and
 * in TORQUE. */
static void test_integral_scheduled_on_stiffness(void)
{
    hd_ctrl_config_t k;
    hd_ctrl_config_default(&k);
    k.torque_ki_per_s = 40.0f;
    k.integral_stiffness_nm_rad = 1500.0f;
    k.integral_limit_nm = 1e4f;
    const double e_nm = 2.0, q = 1e-3; /* kp q within the current limit */
    const double kps[7] = {1.0, 30.0, 100.0, 1000.0, 1500.0, 2000.0, 0.0};
    for (int j = 0; j < 8; j++) {
        const bool torque_mode = j == 7;
        const double kp = torque_mode ? 500.0 : kps[j];
        const double ref = torque_mode ? 5.0 : -kp * q; /* q_d 0, v 0: tau_ref */
        const double ki = (kp > 0.0 && kp < 1500.0 && !torque_mode)
                              ? 40.0 * sqrt(kp / 1500.0)
                              : 40.0;
        hd_ctrl_t c;
        hd_ctrl_plan_t plan;
        TEST_ASSERT_EQUAL_INT(HD_CTRL_OK, hd_ctrl_init(&c, &plan, &k));
        const hd_ctrl_setpoint_t sp = {.mode = torque_mode ? HD_CTRL_TORQUE : HD_CTRL_IMPEDANCE,
                                       .torque_nm = torque_mode ? (float)ref : 0.0f,
                                       .kp_nm_rad = (float)kp, .kd_nm_s_rad = 1.0f};
        const hd_ctrl_input_t in = input_of(ref - e_nm, q, 0.0);
        double u[3];
        for (int n = 0; n < 3; n++) {
            hd_ctrl_output_t o;
            hd_ctrl_step(&c, &sp, &in, &o);
            u[n] = (double)(o.current_a * k.gear_ratio * k.kt_nm_per_a);
        }
        const double growth = u[2] - u[1], expect = ki * (double)k.ts_s * e_nm;
        printf("control: integral at kp %g (%s): %.6f N m per tick, expected %.6f\n", kp,
               torque_mode ? "TORQUE" : "IMPEDANCE", growth, expect);
        TEST_ASSERT_DOUBLE_WITHIN(1e-3 * expect + 2e-6, expect, growth); /* float32 u */
    }
}

int main(int argc, char **argv)
{
    if (UnityParseOptions(argc, argv) != 0) {
        return 1;
    }
    UNITY_BEGIN();
    RUN_TEST(test_config_check);
    RUN_TEST(test_torque_step_first_order_closed_loop);
    RUN_TEST(test_antiwindup_recovers_like_a_fresh_step);
    RUN_TEST(test_integral_bounded_by_its_limit);
    RUN_TEST(test_rate_term_on_the_feedback);
    RUN_TEST(test_friction_at_rest_follows_the_setpoint_rate);
    RUN_TEST(test_impedance_renders_kp);
    RUN_TEST(test_integral_scheduled_on_stiffness);
    RUN_TEST(test_modes_and_fallbacks);
    RUN_TEST(test_velocity_and_position_limits);
    RUN_TEST(test_property_limits_hold_for_any_input);
    RUN_TEST(test_butterworth_feedback_closed_form);
    RUN_TEST(test_order_notch_tracks_the_speed);
    RUN_TEST(test_narrow_feedback_fades_with_motion);
    return UNITY_END();
}
