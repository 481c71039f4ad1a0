/* hal_simdrive: the simulated motor drive (model in hal_simdrive.h). */
#include "hal_simdrive.h"

#include <math.h>
#include <string.h>

#define TWO_PI 6.28318530717958647692

void hal_simdrive_default(hal_simdrive_config_t *cfg)
{
    *cfg = (hal_simdrive_config_t){
        .ts_s = 1e-3,
        .bandwidth_hz = 1500.0,
        .current_limit_a = 20.0,
        .kt_nm_per_a = 0.06,
        .kt_error = 0.0,
        .bus_voltage_v = 24.0,
        .temperature_c = 40.0,
    };
}

int hal_simdrive_init(hal_simdrive_t *d, const hal_simdrive_config_t *cfg)
{
    const bool ok = isfinite(cfg->ts_s) && cfg->ts_s > 0.0 && isfinite(cfg->bandwidth_hz) &&
                    cfg->bandwidth_hz > 0.0 && isfinite(cfg->current_limit_a) &&
                    cfg->current_limit_a > 0.0 && isfinite(cfg->kt_nm_per_a) &&
                    cfg->kt_nm_per_a > 0.0 && isfinite(cfg->kt_error) && cfg->kt_error > -1.0 &&
                    isfinite(cfg->bus_voltage_v) && isfinite(cfg->temperature_c);
    if (!ok) {
        return -1;
    }
    memset(d, 0, sizeof(*d));
    d->cfg = *cfg;
    const double wts = TWO_PI * cfg->bandwidth_hz * cfg->ts_s;
    d->decay = exp(-wts);
    d->mean_factor = (1.0 - d->decay) / wts;
    return 0;
}

static int sd_enable(void *ctx, bool on)
{
    hal_simdrive_t *d = ctx;
    if (on && d->fault) {
        return HAL_ERR_FAULT;
    }
    d->enabled = on;
    return HAL_OK;
}

static int sd_command(void *ctx, float current_a)
{
    hal_simdrive_t *d = ctx;
    if (!isfinite(current_a)) {
        return HAL_ERR_RANGE;
    }
    d->next_a = (double)current_a;
    d->commands++;
    return d->fault ? HAL_ERR_FAULT : HAL_OK;
}

static int sd_status(void *ctx, hal_drive_status_t *out)
{
    const hal_simdrive_t *d = ctx;
    *out = (hal_drive_status_t){.enabled = d->enabled,
                                .fault = d->fault,
                                .fault_code = d->fault_code,
                                .bus_voltage_v = (float)d->cfg.bus_voltage_v,
                                .temperature_c = (float)d->cfg.temperature_c,
                                .current_a = (float)d->current_a,
                                .age_ticks = 0u};
    return HAL_OK;
}

void hal_simdrive_bind(hal_simdrive_t *d, hal_t *hal)
{
    hal->actuator = (hal_actuator_t){.ctx = d,
                                     .enable = sd_enable,
                                     .command_current = sd_command,
                                     .status = sd_status};
}

double hal_simdrive_tick(hal_simdrive_t *d)
{
    if (!d->enabled || d->fault) {
        d->next_a = d->delayed_a = d->ref_a = d->current_a = 0.0;
        return 0.0;
    }
    const double lim = d->cfg.current_limit_a;
    d->ref_a = fmax(-lim, fmin(lim, d->delayed_a)); /* the command of the tick before */
    d->delayed_a = d->next_a;                       /* held until a new one arrives */
    const double i0 = d->current_a;
    d->current_a = d->ref_a + (i0 - d->ref_a) * d->decay;
    /* the torque's mean over the tick: the exact impulse of the lag */
    const double mean_a = d->ref_a + (i0 - d->ref_a) * d->mean_factor;
    return d->cfg.kt_nm_per_a * (1.0 + d->cfg.kt_error) * mean_a;
}

void hal_simdrive_set_fault(hal_simdrive_t *d, bool fault, uint32_t code)
{
    d->fault = fault;
    d->fault_code = fault ? code : 0u;
    if (fault) {
        d->enabled = false;
    }
}
