/*
 * hal_sim: HAL backend fed by the simulated joint (host only).
 *
 * Fills the sensors and clock parts of an hal_t.  Each tick the firmware
 * reads the ADC and the encoder once (either order); the first read of a
 * part that was already read this tick advances the plant one sample.  A
 * scenario with a motor (motor.kt_nm_per_a > 0) also has the current
 * channel: current_read gives the sample of this tick, it never advances.  So
 * adc, enc, adc, enc, ... and an ADC-only loop both step once per call pair
 * or call.  After the last sample every read returns HAL_ERR_END.
 *
 * The ground truth of the current tick (truth torque, angles, velocities)
 * is available through hal_sim_current() so a host runner can print the
 * filter's error against it.
 */
#ifndef HAL_SIM_H
#define HAL_SIM_H

#include <stdbool.h>
#include <stdint.h>

#include "hal.h"
#include "hd_sim_plant.h"
#include "hd_sim_scenario.h"

#ifdef __cplusplus
extern "C" {
#endif

typedef struct {
    hd_sim_plant_t plant;
    hd_sim_sample_t cur;
    bool have_cur;
    bool ended;
    bool adc_taken;
    bool enc_taken;
    uint32_t ts_us;
} hal_sim_t;

/* Starts the simulation at sample 0.  Returns 0 or -1 with a message. */
int hal_sim_init(hal_sim_t *sim, const hd_sim_scenario_t *sc, char *err, size_t err_len);

/* Loads a scenario file and starts it. */
int hal_sim_open(hal_sim_t *sim, const char *scenario_path, char *err, size_t err_len);

/* Fills hal->sensors and hal->clock (and hal->name if NULL); leaves the
 * CAN and NVM parts untouched so other backends can supply them. */
void hal_sim_bind(hal_sim_t *sim, hal_t *hal);

/* The current tick's sample including ground truth; NULL before the first
 * read. */
const hd_sim_sample_t *hal_sim_current(const hal_sim_t *sim);

/* Nominal calibration (gain N m/V, offset V, ADC V/count) and drive
 * constants, for firmware defaults that match the simulated sensor. */
void hal_sim_nominal(const hal_sim_t *sim, hd_sim_nominal_t *out);

/* Total number of ticks in the scenario. */
uint64_t hal_sim_samples(const hal_sim_t *sim);

#ifdef __cplusplus
}
#endif

#endif /* HAL_SIM_H */
