/* The firmware rig (fw_rig.h) with a recording drive: what the control
 * stage tells the drive, for the control and identification tests. */
#ifndef FW_DRIVE_RIG_H
#define FW_DRIVE_RIG_H

#include <math.h>

#include "fw_rig.h"

/* ------------------------------------------------------ recording drive */

typedef struct {
    bool enabled;
    bool fault;           /* reported by status */
    int command_rc;       /* returned by command_current */
    uint32_t enables;     /* enable(true) calls */
    uint32_t commands;
    float last_a;
    float max_abs_a;
    uint32_t non_finite;  /* commands that were not finite */
} rec_drive_t;

static rec_drive_t drv;

static inline int rd_enable(void *ctx, bool on)
{
    rec_drive_t *d = ctx;
    d->enabled = on;
    d->enables += on ? 1u : 0u;
    return HAL_OK;
}

static inline int rd_command(void *ctx, float a)
{
    rec_drive_t *d = ctx;
    d->commands++;
    d->last_a = a;
    d->max_abs_a = fmaxf(d->max_abs_a, fabsf(a));
    d->non_finite += isfinite(a) ? 0u : 1u;
    return d->command_rc;
}

static inline int rd_status(void *ctx, hal_drive_status_t *out)
{
    const rec_drive_t *d = ctx;
    *out = (hal_drive_status_t){.enabled = d->enabled, .fault = d->fault, .bus_voltage_v = NAN,
                                .temperature_c = NAN, .current_a = NAN};
    return HAL_OK;
}

/* counts for a gauge torque of tau (calibration GAIN, OFFSET_V of the rig) */
static inline int32_t counts_of(double tau_nm)
{
    return (int32_t)lround((tau_nm / GAIN + OFFSET_V) / VPC);
}

static inline void start(bool with_drive)
{
    rig_reset();
    cfg.telemetry_rate_hz = 100u; /* the mock's transmit log holds 512 frames */
    cfg.ctrl.position_min_rad = -1.0f;
    cfg.ctrl.position_max_rad = 1.0f;
    memset(&drv, 0, sizeof drv);
    if (with_drive) {
        hal.actuator = (hal_actuator_t){&drv, rd_enable, rd_command, rd_status};
    }
    init_fw();
}

static uint8_t seq_next = 1u;

static inline void push_setpoint(uint8_t mode, float torque_nm, float position_rad, uint8_t seq)
{
    const hd_can_setpoint_t sp = {mode, seq, torque_nm, position_rad, 0.0f};
    hal_can_frame_t f;
    hd_can_encode_setpoint(live_cfg()->node_id, &sp, &f);
    TEST_ASSERT_EQUAL_INT(0, hal_mock_push_rx(&mock, &f));
}

/* One tick with a new setpoint. */
static inline void setpoint_tick(uint8_t mode, float torque_nm)
{
    push_setpoint(mode, torque_nm, 0.0f, seq_next++);
    run(1, counts_of(0.0), 1);
}

#endif /* FW_DRIVE_RIG_H */
