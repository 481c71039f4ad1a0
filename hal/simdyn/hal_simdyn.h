/*
 * hal_simdyn: the dynamic simulated joint (sim/hd_sim_joint) behind the
 * sensors part of an hal_t, with the simulated drive (hal/simdrive) as its
 * actuator part: the firmware closes a real loop on the host (issue 23).
 *
 * Per tick the firmware reads the sensors (the joint's state at the start
 * of the tick), commands the drive; then the runner calls hal_simdyn_tick,
 * which runs the drive's tick and integrates the joint over it.
 * Sensors: the gauge torque (transmitted torque + the sensing artifact)
 * plus white noise of noise_nm, through the nominal calibration into ADC
 * counts (gain, offset, volts per count, 16 bits, rails = saturated);
 * encoders floor(theta cpr / 2 pi) (motor and output).  No current channel.
 * Host only: double, libm.
 */
#ifndef HAL_SIMDYN_H
#define HAL_SIMDYN_H

#include <stdint.h>

#include "hal.h"
#include "hal_simdrive.h"
#include "hd_sim_joint.h"

#ifdef __cplusplus
extern "C" {
#endif

typedef struct {
    double gain_nm_per_v;     /* torque = (counts * volts_per_count - offset_v) * gain */
    double offset_v;
    double volts_per_count;
    double noise_nm;          /* gauge noise, N m rms */
    uint32_t motor_cpr;
    uint32_t output_cpr;
    uint64_t seed;
} hal_simdyn_sensor_t;

typedef struct {
    hd_sim_joint_t joint;
    hal_simdrive_t drive;
    hal_simdyn_sensor_t sens;
    hd_sim_joint_truth_t truth;   /* of the last tick */
    uint64_t rng;
    uint64_t ticks;
} hal_simdyn_t;

/* 6.6 N m/V, 0.1 V, 10 V / 2^15 counts, 0.02 N m noise, 4096-count encoders. */
void hal_simdyn_sensor_default(hal_simdyn_sensor_t *s);

/* 0, or -1 (+ err) for a bad joint or drive configuration. */
int hal_simdyn_init(hal_simdyn_t *d, const hd_sim_joint_params_t *joint,
                    const hal_simdrive_config_t *drive, const hal_simdyn_sensor_t *sens,
                    char *err, size_t err_len);

/* Fills hal->sensors, hal->clock and hal->actuator. */
void hal_simdyn_bind(hal_simdyn_t *d, hal_t *hal);

/* After the firmware's tick: the drive's tick, then the joint over it. */
void hal_simdyn_tick(hal_simdyn_t *d);

#ifdef __cplusplus
}
#endif

#endif /* HAL_SIMDYN_H */
