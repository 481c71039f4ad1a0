/* hal_simdyn: see hal_simdyn.h. */
#include "hal_simdyn.h"

#include <math.h>
#include <string.h>

#define TWO_PI 6.28318530717958647692

void hal_simdyn_sensor_default(hal_simdyn_sensor_t *s)
{
    *s = (hal_simdyn_sensor_t){.gain_nm_per_v = 6.6,
                               .offset_v = 0.1,
                               .volts_per_count = 10.0 / 32768.0,
                               .noise_nm = 0.02,
                               .motor_cpr = 4096u,
                               .output_cpr = 4096u,
                               .seed = 0x5EEDu};
}

int hal_simdyn_init(hal_simdyn_t *d, const hd_sim_joint_params_t *joint,
                    const hal_simdrive_config_t *drive, const hal_simdyn_sensor_t *sens,
                    char *err, size_t err_len)
{
    memset(d, 0, sizeof(*d));
    if (hd_sim_joint_init(&d->joint, joint, err, err_len) != 0) {
        return -1;
    }
    if (hal_simdrive_init(&d->drive, drive) != 0) {
        if (err != NULL && err_len > 0) {
            strncpy(err, "simulated drive: bad configuration", err_len - 1);
            err[err_len - 1] = '\0';
        }
        return -1;
    }
    d->sens = *sens;
    d->rng = sens->seed | 1u;
    return 0;
}

/* xorshift64* and Box-Muller: the gauge noise. */
static double uniform(hal_simdyn_t *d)
{
    d->rng ^= d->rng >> 12;
    d->rng ^= d->rng << 25;
    d->rng ^= d->rng >> 27;
    return ((double)((d->rng * 2685821657736338717ull) >> 11) + 0.5) / 9007199254740992.0;
}

static double gauss(hal_simdyn_t *d)
{
    const double u1 = uniform(d), u2 = uniform(d);
    return sqrt(-2.0 * log(u1)) * cos(TWO_PI * u2);
}

static uint32_t counts_of(double angle_rad, uint32_t cpr)
{
    const double c = floor(angle_rad * (double)cpr / TWO_PI);
    const double m = fmod(c, 4294967296.0);
    return (uint32_t)(m < 0.0 ? m + 4294967296.0 : m);
}

static int dyn_adc(void *ctx, hal_adc_sample_t *out)
{
    hal_simdyn_t *d = ctx;
    const hal_simdyn_sensor_t *s = &d->sens;
    const double tau = hd_sim_joint_gauge_torque_nm(&d->joint) + (s->noise_nm > 0.0 ? s->noise_nm * gauss(d) : 0.0);
    double code = floor((tau / s->gain_nm_per_v + s->offset_v) / s->volts_per_count + 0.5);
    out->saturated = code >= 32767.0 || code <= -32768.0;
    code = fmax(-32768.0, fmin(32767.0, code));
    out->bridge_counts = (int32_t)code;
    return HAL_OK;
}

static int dyn_encoder(void *ctx, hal_encoder_sample_t *out)
{
    const hal_simdyn_t *d = ctx;
    *out = (hal_encoder_sample_t){.motor_counts = counts_of(d->joint.x.motor_angle_rad, d->sens.motor_cpr),
                                  .output_counts = counts_of(d->joint.x.output_angle_rad, d->sens.output_cpr),
                                  .has_output = d->sens.output_cpr > 0u,
                                  .fault = false};
    return HAL_OK;
}

static uint64_t dyn_time_us(void *ctx)
{
    const hal_simdyn_t *d = ctx;
    return d->ticks * (uint64_t)llround(d->joint.p.ts_s * 1e6);
}

void hal_simdyn_bind(hal_simdyn_t *d, hal_t *hal)
{
    hal->sensors = (hal_sensors_t){.ctx = d, .adc_read = dyn_adc, .encoder_read = dyn_encoder,
                                   .current_read = NULL};
    hal->clock = (hal_clock_t){.ctx = d, .time_us = dyn_time_us};
    hal_simdrive_bind(&d->drive, hal);
    if (hal->name == NULL) {
        hal->name = "simdyn";
    }
}

void hal_simdyn_tick(hal_simdyn_t *d)
{
    const double tm = hal_simdrive_tick(&d->drive);
    hd_sim_joint_step(&d->joint, tm, &d->truth);
    d->ticks++;
}
