#include "hd_sim_plant.h"

#include <math.h>
#include <stdio.h>
#include <string.h>

#define TWO_PI 6.283185307179586476925

/* ------------------------------------------------------------------ random numbers
 * xoshiro256** seeded through splitmix64: fixed algorithm, so a seed gives
 * the same run on every host (unlike rand()). */

static uint64_t splitmix64(uint64_t *s)
{
    uint64_t z = (*s += 0x9E3779B97F4A7C15ull);
    z = (z ^ (z >> 30)) * 0xBF58476D1CE4E5B9ull;
    z = (z ^ (z >> 27)) * 0x94D049BB133111EBull;
    return z ^ (z >> 31);
}

static uint64_t rotl(uint64_t x, int k)
{
    return (x << k) | (x >> (64 - k));
}

static uint64_t rng_next(uint64_t s[4])
{
    const uint64_t result = rotl(s[1] * 5u, 7) * 9u;
    const uint64_t t = s[1] << 17;
    s[2] ^= s[0];
    s[3] ^= s[1];
    s[1] ^= s[2];
    s[0] ^= s[3];
    s[2] ^= t;
    s[3] = rotl(s[3], 45);
    return result;
}

/* Uniform in (0, 1]. */
static double rng_uniform(uint64_t s[4])
{
    return ((double)(rng_next(s) >> 11) + 1.0) * (1.0 / 9007199254740992.0);
}

/* Standard normal (Box-Muller, both values used). */
static double rng_gauss(hd_sim_plant_t *p)
{
    if (p->has_spare) {
        p->has_spare = false;
        return p->spare;
    }
    const double r = sqrt(-2.0 * log(rng_uniform(p->rng)));
    const double a = TWO_PI * rng_uniform(p->rng);
    p->spare = r * sin(a);
    p->has_spare = true;
    return r * cos(a);
}

/* ------------------------------------------------------------------ nominal calibration */

static double adc_lsb_v(const hd_sim_scenario_t *sc)
{
    return 2.0 * sc->adc_range_v / ldexp(1.0, sc->adc_bits);
}

void hd_sim_nominal(const hd_sim_scenario_t *sc, hd_sim_nominal_t *out)
{
    memset(out, 0, sizeof(*out));
    out->gain_nm_per_v = isnan(sc->cal_gain_nm_per_v)
                             ? (double)hd_bridge_gain_nm_per_v(&sc->bridge)
                             : sc->cal_gain_nm_per_v;
    out->offset_v = isnan(sc->cal_offset_v) ? sc->bridge_offset_v : sc->cal_offset_v;
    out->adc_v_per_count = adc_lsb_v(sc);
    out->adc_bits = sc->adc_bits;
    out->gear_ratio = sc->gear_ratio;
    out->motor_cpr = sc->encoder_cpr;
    out->output_cpr = sc->output_encoder_cpr;
    out->ts_s = sc->ts_s;
    out->load_inertia_kgm2 = sc->load_inertia_kgm2;
    out->viscous_nm_s_rad = sc->viscous_nm_s_rad;
    out->coulomb_nm = sc->coulomb_nm;
    out->motor_kt_nm_per_a = sc->motor.kt_nm_per_a;
}

/* ------------------------------------------------------------------ kinematics */

int hd_sim_plant_init(hd_sim_plant_t *p, const hd_sim_scenario_t *sc, char *err, size_t err_len)
{
    if (p == NULL || sc == NULL) {
        if (err != NULL && err_len > 0) {
            snprintf(err, err_len, "hd_sim_plant_init: NULL argument");
        }
        return -1;
    }
    if (hd_sim_scenario_validate(sc, err, err_len) != 0) {
        return -1;
    }
    memset(p, 0, sizeof(*p));
    p->sc = *sc;
    p->n_samples = hd_sim_scenario_samples(sc);
    /* Exact integral of the piecewise-linear speed up to each breakpoint. */
    const hd_sim_profile_t *w = &p->sc.motor_speed;
    if (w->n > 0) {
        p->seg_angle_rad[0] = sc->motor_angle0_rad + w->value[0] * w->t_s[0];
        for (size_t i = 1; i < w->n; i++) {
            const double dt = w->t_s[i] - w->t_s[i - 1];
            p->seg_angle_rad[i] = p->seg_angle_rad[i - 1] + 0.5 * (w->value[i - 1] + w->value[i]) * dt;
        }
    }
    uint64_t s = sc->seed;
    for (int i = 0; i < 4; i++) {
        p->rng[i] = splitmix64(&s);
    }
    hd_sim_nominal(sc, &p->nominal);
    return 0;
}

void hd_sim_motor_kinematics(const hd_sim_plant_t *p, double t_s, double *angle_rad,
                             double *velocity_rad_s, double *accel_rad_s2)
{
    const hd_sim_profile_t *w = &p->sc.motor_speed;
    double ang = p->sc.motor_angle0_rad, vel = 0.0, acc = 0.0;
    if (w->n > 0) {
        if (t_s < w->t_s[0]) {
            vel = w->value[0];
            ang = p->sc.motor_angle0_rad + vel * t_s;
        } else {
            size_t i = 1;
            while (i < w->n && t_s >= w->t_s[i]) {
                i++;
            }
            if (i == w->n) { /* after the last point: hold */
                vel = w->value[w->n - 1];
                ang = p->seg_angle_rad[w->n - 1] + vel * (t_s - w->t_s[w->n - 1]);
            } else {
                const double dt = t_s - w->t_s[i - 1];
                acc = (w->value[i] - w->value[i - 1]) / (w->t_s[i] - w->t_s[i - 1]);
                vel = w->value[i - 1] + acc * dt;
                ang = p->seg_angle_rad[i - 1] + w->value[i - 1] * dt + 0.5 * acc * dt * dt;
            }
        }
    }
    *angle_rad = ang;
    *velocity_rad_s = vel;
    *accel_rad_s2 = acc;
}

static double sgn(double x)
{
    return (x > 0.0) - (x < 0.0);
}

/* floor(angle * cpr / 2 pi) reduced modulo 2^32, as a free-running counter. */
static uint32_t encoder_counts(double angle_rad, uint32_t cpr)
{
    const double c = floor(angle_rad * (double)cpr / TWO_PI);
    const double m = fmod(c, 4294967296.0);
    const double w = m < 0.0 ? m + 4294967296.0 : m;
    return (uint32_t)w;
}

/* ------------------------------------------------------------------ one sample */

static double sensor_lines_nm(const hd_sim_scenario_t *sc, const hd_sim_sample_t *s)
{
    const double load_scale = 1.0 + sc->ripple_load_coeff_per_nm * fabs(s->torque_true_nm);
    double sum = 0.0;
    for (size_t i = 0; i < sc->ripple_count; i++) {
        const hd_sim_ripple_t *r = &sc->ripples[i];
        double arg, amp = r->amplitude_nm * load_scale;
        if (r->kind == HD_SIM_RIPPLE_MOTOR) {
            arg = r->order * s->motor_angle_rad;
        } else if (r->kind == HD_SIM_RIPPLE_OUTPUT) {
            arg = r->order * s->output_angle_rad;
        } else {
            /* index * ts rather than accumulated t: exact phase on long runs */
            arg = TWO_PI * fmod(r->order * (double)s->index * sc->ts_s, 1.0);
            amp = r->amplitude_nm;
        }
        sum += amp * sin(arg + r->phase_rad);
    }
    return sum;
}

static bool in_windows(const hd_sim_window_t *w, size_t n, double t_s)
{
    for (size_t i = 0; i < n; i++) {
        if (t_s >= w[i].t_start_s && t_s < w[i].t_end_s) {
            return true;
        }
    }
    return false;
}

static bool in_fault_window(const hd_sim_scenario_t *sc, double t_s)
{
    return in_windows(sc->encoder_faults, sc->encoder_fault_count, t_s);
}

static double load_sines_nm(const hd_sim_scenario_t *sc, double t_s)
{
    double sum = 0.0;
    for (size_t i = 0; i < sc->load_sine_count; i++) {
        const hd_sim_sine_t *w = &sc->load_sines[i];
        sum += w->amplitude_nm * sin(TWO_PI * fmod(t_s / w->period_s, 1.0) + w->phase_rad);
    }
    return sum;
}

/* The robot controller's model of the same torque: its own gravity and
 * dynamics parameters, the share of the external load it knows, noise. */
static double feedforward_nm(hd_sim_plant_t *p, const hd_sim_sample_t *s, double acc_o)
{
    const hd_sim_feedforward_t *f = &p->sc.ff;
    const hd_sim_profile_t *g = f->gravity.n > 0 ? &f->gravity : &p->sc.gravity;
    const double w = s->output_velocity_rad_s;
    double v = f->gravity_scale * hd_sim_profile_eval(g, s->t_s) *
                   sin(s->output_angle_rad + p->sc.gravity_phase_rad + f->gravity_phase_error_rad) +
               f->load_scale * s->load_torque_nm + f->inertia_kgm2 * acc_o + f->viscous_nm_s_rad * w +
               f->coulomb_nm * sgn(w);
    if (f->noise_nm > 0.0) {
        v += f->noise_nm * rng_gauss(p);
    }
    return v;
}

/* The motor current that drives this motion against the transmitted
 * torque: the gear passes T_true / (N eta) when the motor drives the load
 * and T_true eta_b / N when the load drives the motor; the motor also
 * accelerates its rotor and overcomes its own friction.  The drive's
 * measurement adds noise; kt_true = kt (1 + kt_error). */
static double motor_current_a(hd_sim_plant_t *p, const hd_sim_sample_t *s, double acc_m)
{
    const hd_sim_motor_t *m = &p->sc.motor;
    const double n = p->sc.gear_ratio;
    const double t = s->torque_true_nm;
    const bool motoring = t * s->output_velocity_rad_s >= 0.0;
    const double gear = motoring ? t / (n * m->efficiency) : t * m->backdrive_efficiency / n;
    const double wm = s->motor_velocity_rad_s;
    const double tm = gear + m->inertia_kgm2 * acc_m + m->viscous_nm_s_rad * wm +
                      m->coulomb_nm * sgn(wm);
    double i = tm / (m->kt_nm_per_a * (1.0 + m->kt_error));
    if (m->current_noise_a > 0.0) {
        i += m->current_noise_a * rng_gauss(p);
    }
    return i;
}

int hd_sim_plant_next(hd_sim_plant_t *p, hd_sim_sample_t *s)
{
    if (p->next >= p->n_samples) {
        return 1;
    }
    const hd_sim_scenario_t *sc = &p->sc;
    memset(s, 0, sizeof(*s));
    s->index = p->next++;
    s->t_s = (double)s->index * sc->ts_s;

    double acc_m;
    hd_sim_motor_kinematics(p, s->t_s, &s->motor_angle_rad, &s->motor_velocity_rad_s, &acc_m);
    s->output_angle_rad = s->motor_angle_rad / sc->gear_ratio;
    s->output_velocity_rad_s = s->motor_velocity_rad_s / sc->gear_ratio;
    s->output_accel_rad_s2 = acc_m / sc->gear_ratio;

    /* Truth: what the flexspline really transmits. */
    const double w = s->output_velocity_rad_s;
    const double ws = sc->stribeck_velocity_rad_s;
    s->load_torque_nm = hd_sim_profile_eval(&sc->load_torque, s->t_s) + load_sines_nm(sc, s->t_s);
    s->gravity_nm = hd_sim_profile_eval(&sc->gravity, s->t_s) *
                    sin(s->output_angle_rad + sc->gravity_phase_rad);
    s->torque_true_nm = sc->load_inertia_kgm2 * s->output_accel_rad_s2 + sc->viscous_nm_s_rad * w +
                        sc->coulomb_nm * sgn(w) + sc->stribeck_nm * exp(-(w / ws) * (w / ws)) * sgn(w) +
                        s->load_torque_nm + s->gravity_nm;

    /* Sensor: lines, offset, then the bridge (which adds its own 2x residual). */
    const double offset_nm = sc->offset_nm + sc->offset_drift_nm_per_s * s->t_s + p->offset_walk_nm;
    if (sc->offset_random_walk_nm_per_sqrt_s > 0.0) {
        p->offset_walk_nm += sc->offset_random_walk_nm_per_sqrt_s * sqrt(sc->ts_s) * rng_gauss(p);
    }
    const double sensed_nm = s->torque_true_nm + sensor_lines_nm(sc, s) + offset_nm;
    const float beta = (float)fmod(s->motor_angle_rad, TWO_PI);
    const double v_clean = (double)hd_bridge_output_v(&sc->bridge, (float)sensed_nm, beta) +
                           sc->bridge_offset_v;
    const hd_sim_nominal_t *nom = &p->nominal;
    s->ripple_true_nm = (v_clean - nom->offset_v) * nom->gain_nm_per_v - s->torque_true_nm;

    const double n_nm = sc->noise_nm > 0.0 ? sc->noise_nm * rng_gauss(p) : 0.0;
    const double n_v = sc->noise_v > 0.0 ? sc->noise_v * rng_gauss(p) : 0.0;
    s->bridge_v = (double)hd_bridge_output_v(&sc->bridge, (float)(sensed_nm + n_nm), beta) +
                  sc->bridge_offset_v + n_v;

    /* ADC: mid-tread quantiser, clipped to the code range; the rail codes
     * are reported as saturated (the converter cannot tell beyond them). */
    const double lsb = nom->adc_v_per_count;
    const double code_max = ldexp(1.0, sc->adc_bits - 1) - 1.0;
    const double code_min = -ldexp(1.0, sc->adc_bits - 1);
    double code = floor(s->bridge_v / lsb + 0.5);
    if (!isfinite(code)) {
        code = code_max;
    }
    if (code >= code_max) {
        code = code_max;
        s->saturated = true;
    } else if (code <= code_min) {
        code = code_min;
        s->saturated = true;
    }
    s->bridge_counts = (int32_t)code;
    s->torque_nm = ((double)s->bridge_counts * lsb - nom->offset_v) * nom->gain_nm_per_v;

    s->motor_counts = encoder_counts(s->motor_angle_rad, sc->encoder_cpr);
    s->has_output = sc->output_encoder_cpr > 0;
    s->output_counts = s->has_output ? encoder_counts(s->output_angle_rad, sc->output_encoder_cpr) : 0u;
    s->encoder_fault = in_fault_window(sc, s->t_s);

    /* Drawn after the sensor's noise so scenarios without them keep their
     * random stream (and their numbers). */
    s->feedforward_nm = (double)NAN;
    if (sc->ff.enabled) {
        s->feedforward_nm = feedforward_nm(p, s, s->output_accel_rad_s2);
        s->feedforward_sent = s->index % sc->ff.period_ms == 0u &&
                              !in_windows(sc->ff.dropouts, sc->ff.dropout_count, s->t_s);
    }
    s->motor_current_a = sc->motor.kt_nm_per_a > 0.0 ? motor_current_a(p, s, acc_m) : (double)NAN;
    return 0;
}
