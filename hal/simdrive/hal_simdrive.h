/*
 * hal_simdrive: the simulated motor drive, an hal_actuator_t (host only;
 * issue 23).  Between the firmware's current command and the motor torque
 * the dynamic joint (sim/hd_sim_joint) receives:
 *   - one tick of transport delay: the command of tick k is the current
 *     loop's reference over tick k + 1 (the interval after the runner's
 *     hal_simdrive_tick of tick k + 1), and is held until the next one;
 *   - saturation of the reference to +-current_limit_a (the drive's own);
 *   - the current loop as a first-order lag of bandwidth bandwidth_hz,
 *     integrated exactly over a tick for a held reference:
 *       i <- ref + (i - ref) exp(-2 pi f ts)
 *   - a torque-constant error: torque = kt (1 + kt_error) i, while the
 *     firmware converts with the nominal kt.
 * Disabled, or faulted, the current is 0 at once (the stage is off).
 * The runner calls hal_simdrive_tick once per tick, after the firmware's
 * tick: it returns the motor torque to hold over the next interval (the
 * lag's mean over it, so the impulse the joint receives is exact).
 */
#ifndef HAL_SIMDRIVE_H
#define HAL_SIMDRIVE_H

#include <stdbool.h>
#include <stdint.h>

#include "hal.h"

#ifdef __cplusplus
extern "C" {
#endif

typedef struct {
    double ts_s;
    double bandwidth_hz;        /* current loop */
    double current_limit_a;     /* the drive's own saturation */
    double kt_nm_per_a;         /* nominal (what the firmware is told) */
    double kt_error;            /* true kt = kt (1 + kt_error) */
    double bus_voltage_v;
    double temperature_c;
} hal_simdrive_config_t;

typedef struct {
    hal_simdrive_config_t cfg;
    double decay;               /* exp(-2 pi f ts) */
    double mean_factor;         /* (1 - decay) / (2 pi f ts) */
    bool enabled;
    bool fault;                 /* set by a test or a scenario: the drive trips */
    uint32_t fault_code;
    double next_a;              /* commanded this tick */
    double delayed_a;           /* in transit: the loop's reference from the next tick */
    double ref_a;               /* the current loop's reference (the tick before's command) */
    double current_a;           /* the motor's q-axis current */
    uint32_t commands;          /* command_current calls */
} hal_simdrive_t;

/* 1 kHz, 1.5 kHz current loop, 20 A, kt 0.06 N m/A exact, 24 V, 40 C. */
void hal_simdrive_default(hal_simdrive_config_t *cfg);

/* 0, or -1 for a configuration value non-finite or out of range. */
int hal_simdrive_init(hal_simdrive_t *d, const hal_simdrive_config_t *cfg);

/* Fills hal->actuator only. */
void hal_simdrive_bind(hal_simdrive_t *d, hal_t *hal);

/* One tick of the drive; returns the motor torque (N m) over the next tick. */
double hal_simdrive_tick(hal_simdrive_t *d);

/* The drive trips (true) or its fault is cleared (false; it stays disabled). */
void hal_simdrive_set_fault(hal_simdrive_t *d, bool fault, uint32_t code);

#ifdef __cplusplus
}
#endif

#endif /* HAL_SIMDRIVE_H */
