/* hd_slow: see hd_slow.h. */
#include "hd_slow.h"

#include "hd_float.h"
#include "hd_trig.h"

void hd_slow_current_config(hd_slow_current_config_t *c, const hd_expected_current_config_t *term,
                            float filter_hz, float gear_ratio, float ts_s)
{
    c->term = *term;
    /* y += alpha (x - y): alpha = w / (1 + w), w = 2 pi f ts (backward Euler) */
    const float w = HD_TWO_PI_F * filter_hz * ts_s;
    c->alpha = (filter_hz > 0.0f) ? w / (1.0f + w) : 1.0f;
    c->lag_steps = 2.0f * (1.0f - c->alpha) / c->alpha;
    c->gear_ratio = gear_ratio;
    c->ts_s = ts_s;
}

/* Both stages of every input advanced by one step; returns the derivative
 * of the filtered velocity (0 on the step that primes them). */
static float low_pass(hd_slow_current_t *st, float a, float current_a, float w)
{
    if (!st->primed) {
        st->i1_a = st->i2_a = current_a;
        st->w1_rad_s = st->w2_rad_s = w;
        st->primed = 1u;
        return 0.0f;
    }
    st->i1_a += a * (current_a - st->i1_a);
    st->i2_a += a * (st->i1_a - st->i2_a);
    st->w1_rad_s += a * (w - st->w1_rad_s);
    const float dw = a * (st->w1_rad_s - st->w2_rad_s);
    st->w2_rad_s += dw;
    return dw;
}

float hd_slow_current_nm(hd_slow_current_t *st, const hd_slow_current_config_t *c,
                         const hd_expected_config_t *e, float motor_current_a,
                         float output_velocity_rad_s, float *var_nm2)
{
    *var_nm2 = 0.0f;
    if (!(c->term.nm_per_a > 0.0f) || !is_finite(motor_current_a)) {
        st->primed = 0u;
        return 0.0f;
    }
    const int first = !st->primed;
    const float acc = low_pass(st, c->alpha, motor_current_a, output_velocity_rad_s) / c->ts_s;
    const float t = hd_expected_current_nm(&c->term, e, st->i2_a, st->w2_rad_s, acc);
    const float lead_nm = first ? 0.0f : c->lag_steps * (t - st->torque_nm);
    st->torque_nm = t;
    float spread_nm = 0.0f;
    if (c->term.coulomb_nm > 0.0f) { /* two divisions only where there is a Coulomb term */
        const float dv = abs_f(acc) * c->lag_steps * c->ts_s + e->coulomb_vel_eps_rad_s;
        spread_nm = 0.5f * c->term.coulomb_nm *
                    (smooth_sign_f(st->w2_rad_s + dv, e->coulomb_vel_eps_rad_s) -
                     smooth_sign_f(st->w2_rad_s - dv, e->coulomb_vel_eps_rad_s));
    }
    *var_nm2 = lead_nm * lead_nm + spread_nm * spread_nm + c->term.error_nm * c->term.error_nm;
    return t + lead_nm;
}

float hd_slow_feedforward_ramp_nm(float last_nm, uint32_t stale_ticks, uint32_t ramp_ticks)
{
    if (stale_ticks >= ramp_ticks) {
        return 0.0f;
    }
    return last_nm * (1.0f - (float)stale_ticks / (float)ramp_ticks);
}
