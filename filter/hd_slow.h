/*
 * hd_slow: the slow torque the filter is given (T_exp and the variance of
 * its error), assembled in this one place.  The firmware's tick and
 * hd_pipeline_run (so `hdsense analyze`) both reach it through
 * hd_pipeline_sample; nothing else adds up T_exp.
 *
 *   T_exp = J acc + b vel + Fc sgn(vel) + (T_ff + T_cur)    (hd_expected.h)
 *
 *   vel, acc  the output tracker's (hd_track), after this sample's increment
 *   T_ff      the robot controller's feed-forward as the caller latched it;
 *             hd_slow_feedforward_ramp_nm is its stale fallback
 *   T_cur     the motor-current term of hd_expected.h on inputs low-passed
 *             alike through two first-order stages (gain alpha per step):
 *             the current, the output velocity from the motor increments
 *             (1/N finer than an output encoder) and the derivative of the
 *             filtered velocity.  Unfiltered, the drive's current noise and
 *             the rotor's inertia torque against a lagging acceleration
 *             would enter the innovation (docs/design/slow-torque.md, "Motor
 *             current").
 *             T_cur is the model's value plus lag_steps x its change per
 *             step: the two stages lag a ramp by lag_steps samples, and
 *             the change extrapolates that lag away (a first-order lead;
 *             on a step it overshoots by 1/e at most, which var covers).
 *   var       the sum of three squares: the lead's own size (what a wrong
 *             extrapolation can cost); the Coulomb term's spread,
 *             Fc_r (sgn(v + dv) - sgn(v - dv)) / 2 with the smoothed sign,
 *             over the velocity the lag leaves unknown, dv = |acc| x
 *             lag_steps x ts + v_eps (near a stop the friction's sign, and
 *             at a standstill its value, is not known: Fc_r / 2 there); and
 *             term.error_nm, what the model misses beyond its lag.  The
 *             filter is told so instead of learning these as ripple.
 *
 * Contract: one call per sample, in sample order; a sample without a
 * usable current (NaN, or term.nm_per_a = 0) gives T_cur = 0, var = 0 and
 * primes the stages again from the next current.  Bounded time, no loops.
 * Pure: no I/O, no heap, no globals; the state is the caller's.
 */
#ifndef HD_SLOW_H
#define HD_SLOW_H

#include <stdint.h>

#include "hd_expected.h"

#ifdef __cplusplus
extern "C" {
#endif

/* How T_cur is formed; hd_slow_current_config fills it. */
typedef struct {
    hd_expected_current_config_t term; /* all zero: no current term */
    float alpha;                       /* low-pass gain per step (1 = none) */
    float lag_steps;                   /* the two stages' lag behind a ramp: 2 (1 - alpha) / alpha */
    float gear_ratio;                  /* motor radians per output radian */
    float ts_s;                        /* sample period */
} hd_slow_current_config_t;

/* The current estimator's state (all zero: not primed). */
typedef struct {
    float i1_a, i2_a;            /* the current after each stage */
    float w1_rad_s, w2_rad_s;    /* the output velocity from the motor increments */
    float torque_nm;             /* T_cur at the last step (its change: the lag's size) */
    uint8_t primed;
} hd_slow_current_t;

/* alpha from the corner filter_hz (backward Euler: w / (1 + w), w = 2 pi f
 * ts; filter_hz <= 0: no low-pass), lag_steps from alpha. */
void hd_slow_current_config(hd_slow_current_config_t *c, const hd_expected_current_config_t *term,
                            float filter_hz, float gear_ratio, float ts_s);

/* The output velocity the current term uses, from one motor increment:
 * d_motor / (N ts).  The firmware's one motor velocity is this times N. */
static inline float hd_slow_output_velocity_rad_s(const hd_slow_current_config_t *c,
                                                  float d_motor_angle_rad)
{
    return d_motor_angle_rad / (c->gear_ratio * c->ts_s);
}

/* T_cur for this sample (0 without a usable current); *var_nm2 its error
 * variance.  e: the expected-torque model (its v_eps smooths the signs). */
float hd_slow_current_nm(hd_slow_current_t *st, const hd_slow_current_config_t *c,
                         const hd_expected_config_t *e, float motor_current_a,
                         float output_velocity_rad_s, float *var_nm2);

/* The feed-forward after stale_ticks ticks without a fresh value: the last
 * one ramped to zero over ramp_ticks (0: dropped at once). */
float hd_slow_feedforward_ramp_nm(float last_nm, uint32_t stale_ticks, uint32_t ramp_ticks);

#ifdef __cplusplus
}
#endif

#endif /* HD_SLOW_H */
