#include "hal_sim.h"

#include <math.h>
#include <string.h>

int hal_sim_init(hal_sim_t *sim, const hd_sim_scenario_t *sc, char *err, size_t err_len)
{
    if (sim == NULL) {
        return -1;
    }
    memset(sim, 0, sizeof(*sim));
    if (hd_sim_plant_init(&sim->plant, sc, err, err_len) != 0) {
        return -1;
    }
    sim->ts_us = (uint32_t)floor(sc->ts_s * 1e6 + 0.5);
    return 0;
}

int hal_sim_open(hal_sim_t *sim, const char *scenario_path, char *err, size_t err_len)
{
    hd_sim_scenario_t sc;
    hd_sim_scenario_default(&sc);
    if (hd_sim_scenario_load(&sc, scenario_path, err, err_len) != 0) {
        return -1;
    }
    return hal_sim_init(sim, &sc, err, err_len);
}

/* Moves to the next tick when the requested part was already read. */
static int tick_for(hal_sim_t *sim, bool *taken)
{
    if (sim->ended) {
        return HAL_ERR_END;
    }
    if (!sim->have_cur || *taken) {
        if (hd_sim_plant_next(&sim->plant, &sim->cur) != 0) {
            sim->ended = true;
            return HAL_ERR_END;
        }
        sim->have_cur = true;
        sim->adc_taken = false;
        sim->enc_taken = false;
    }
    *taken = true;
    return HAL_OK;
}

static int sim_adc_read(void *ctx, hal_adc_sample_t *out)
{
    hal_sim_t *sim = ctx;
    if (sim == NULL || out == NULL) {
        return HAL_ERR_RANGE;
    }
    int rc = tick_for(sim, &sim->adc_taken);
    if (rc != HAL_OK) {
        return rc;
    }
    out->bridge_counts = sim->cur.bridge_counts;
    out->saturated = sim->cur.saturated;
    return HAL_OK;
}

static int sim_encoder_read(void *ctx, hal_encoder_sample_t *out)
{
    hal_sim_t *sim = ctx;
    if (sim == NULL || out == NULL) {
        return HAL_ERR_RANGE;
    }
    int rc = tick_for(sim, &sim->enc_taken);
    if (rc != HAL_OK) {
        return rc;
    }
    out->motor_counts = sim->cur.motor_counts;
    out->output_counts = sim->cur.output_counts;
    out->has_output = sim->cur.has_output;
    out->fault = sim->cur.encoder_fault;
    return HAL_OK;
}

/* The drive's current of the sample the ADC and encoders gave this tick. */
static int sim_current_read(void *ctx, hal_current_sample_t *out)
{
    hal_sim_t *sim = ctx;
    if (sim == NULL || out == NULL) {
        return HAL_ERR_RANGE;
    }
    if (sim->ended || !sim->have_cur) {
        return HAL_ERR_NO_DATA;
    }
    out->motor_current_a = (float)sim->cur.motor_current_a;
    out->fault = false;
    return HAL_OK;
}

static uint64_t sim_time_us(void *ctx)
{
    const hal_sim_t *sim = ctx;
    if (sim == NULL || !sim->have_cur) {
        return 0;
    }
    return sim->cur.index * (uint64_t)sim->ts_us;
}

void hal_sim_bind(hal_sim_t *sim, hal_t *hal)
{
    if (hal == NULL) {
        return;
    }
    if (hal->name == NULL) {
        hal->name = "sim";
    }
    hal->sensors.ctx = sim;
    hal->sensors.adc_read = sim_adc_read;
    hal->sensors.encoder_read = sim_encoder_read;
    hal->sensors.current_read = sim->plant.sc.motor.kt_nm_per_a > 0.0 ? sim_current_read : NULL;
    hal->clock.ctx = sim;
    hal->clock.time_us = sim_time_us;
}

const hd_sim_sample_t *hal_sim_current(const hal_sim_t *sim)
{
    return (sim != NULL && sim->have_cur) ? &sim->cur : NULL;
}

void hal_sim_nominal(const hal_sim_t *sim, hd_sim_nominal_t *out)
{
    *out = sim->plant.nominal;
}

uint64_t hal_sim_samples(const hal_sim_t *sim)
{
    return sim->plant.n_samples;
}
