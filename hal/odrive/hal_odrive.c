/* hal_odrive: see hal_odrive.h. */
#include "hal_odrive.h"

#include <math.h> /* NAN: a compiler builtin, no libm call */
#include <string.h>

#include "hd_record_store.h" /* the project's little-endian helpers */

static void frame(uint8_t node, uint32_t cmd, uint8_t len, hal_can_frame_t *f)
{
    memset(f, 0, sizeof *f);
    f->id = ((uint32_t)(node & 0x3Fu) << 5) | cmd;
    f->len = len;
    f->flags = 0u; /* 11-bit */
}

void hal_odrive_encode_set_axis_state(uint8_t node, uint32_t state, hal_can_frame_t *f)
{
    frame(node, HAL_ODRIVE_CMD_SET_AXIS_STATE, 8u, f);
    hd_le_put_u32(&f->data[0], state);
}

void hal_odrive_encode_set_controller_mode(uint8_t node, uint32_t control_mode,
                                           uint32_t input_mode, hal_can_frame_t *f)
{
    frame(node, HAL_ODRIVE_CMD_SET_CONTROLLER_MODE, 8u, f);
    hd_le_put_u32(&f->data[0], control_mode);
    hd_le_put_u32(&f->data[4], input_mode);
}

void hal_odrive_encode_set_input_torque(uint8_t node, float torque_nm, hal_can_frame_t *f)
{
    frame(node, HAL_ODRIVE_CMD_SET_INPUT_TORQUE, 8u, f);
    hd_le_put_f32(&f->data[0], torque_nm);
}

void hal_odrive_encode_clear_errors(uint8_t node, hal_can_frame_t *f)
{
    frame(node, HAL_ODRIVE_CMD_CLEAR_ERRORS, 1u, f); /* Identify = 0 (0.6.x; 0.5.6 ignores it) */
}

/* The command of an 11-bit CAN Simple frame of this node, or 0xFF. */
static uint32_t command_of(const hal_can_frame_t *f, uint8_t node)
{
    if ((f->flags & (HAL_CAN_FLAG_EXT | HAL_CAN_FLAG_ERR | HAL_CAN_FLAG_RTR)) != 0u ||
        (f->id >> 5) != (uint32_t)(node & 0x3Fu)) {
        return 0xFFu;
    }
    return f->id & 0x1Fu;
}

int hal_odrive_decode_heartbeat(const hal_can_frame_t *f, hal_odrive_heartbeat_t *out)
{
    if (command_of(f, (uint8_t)(f->id >> 5)) != HAL_ODRIVE_CMD_HEARTBEAT || f->len < 7u) {
        return HAL_ERR_FORMAT;
    }
    out->axis_error = hd_le_get_u32(&f->data[0]);
    out->axis_state = f->data[4];
    out->procedure_result = f->data[5];
    out->trajectory_done = (f->data[6] & 1u) != 0u;
    return HAL_OK;
}

void hal_odrive_init(hal_odrive_t *d, const hal_can_t *bus, uint8_t node, float kt_nm_per_a)
{
    memset(d, 0, sizeof *d);
    d->bus = bus;
    d->node = node;
    d->kt_nm_per_a = kt_nm_per_a;
    d->bus_voltage_v = d->iq_measured_a = d->temperature_c = NAN;
}

static int send(const hal_odrive_t *d, const hal_can_frame_t *f)
{
    return (d->bus == NULL || d->bus->send == NULL) ? HAL_ERR_IO : d->bus->send(d->bus->ctx, f);
}

static int od_enable(void *ctx, bool on)
{
    hal_odrive_t *d = ctx;
    hal_can_frame_t f;
    int rc = HAL_OK;
    if (on) {
        hal_odrive_encode_clear_errors(d->node, &f);
        rc = send(d, &f);
        hal_odrive_encode_set_controller_mode(d->node, HAL_ODRIVE_CONTROL_MODE_TORQUE,
                                              HAL_ODRIVE_INPUT_MODE_PASSTHROUGH, &f);
        rc = rc != HAL_OK ? rc : send(d, &f);
    }
    hal_odrive_encode_set_axis_state(
        d->node, on ? HAL_ODRIVE_AXIS_STATE_CLOSED_LOOP : HAL_ODRIVE_AXIS_STATE_IDLE, &f);
    rc = rc != HAL_OK ? rc : send(d, &f);
    d->enabled = on && rc == HAL_OK;
    return rc;
}

static int od_command(void *ctx, float current_a)
{
    hal_odrive_t *d = ctx;
    if (!(current_a - current_a == 0.0f)) {
        return HAL_ERR_RANGE;
    }
    hal_can_frame_t f;
    hal_odrive_encode_set_input_torque(d->node, current_a * d->kt_nm_per_a, &f);
    return send(d, &f);
}

static void take(hal_odrive_t *d, const hal_can_frame_t *f)
{
    const uint32_t cmd = command_of(f, d->node);
    if (cmd == HAL_ODRIVE_CMD_HEARTBEAT && hal_odrive_decode_heartbeat(f, &d->hb) == HAL_OK) {
        d->have_heartbeat = true;
        d->age_ticks = 0u;
    } else if (f->len == 8u && cmd == HAL_ODRIVE_CMD_GET_BUS_VOLTAGE_CURRENT) {
        d->bus_voltage_v = hd_le_get_f32(&f->data[0]);
    } else if (f->len == 8u && cmd == HAL_ODRIVE_CMD_GET_IQ) {
        d->iq_measured_a = hd_le_get_f32(&f->data[4]);
    } else if (f->len == 8u && cmd == HAL_ODRIVE_CMD_GET_TEMPERATURE) {
        d->temperature_c = hd_le_get_f32(&f->data[4]);
    }
}

static int od_status(void *ctx, hal_drive_status_t *out)
{
    hal_odrive_t *d = ctx;
    if (d->age_ticks < UINT32_MAX) {
        d->age_ticks++;
    }
    for (unsigned i = 0; i < HAL_ODRIVE_RX_PER_CALL && d->bus != NULL && d->bus->recv != NULL; i++) {
        hal_can_frame_t f;
        if (d->bus->recv(d->bus->ctx, &f) != HAL_OK) {
            break;
        }
        take(d, &f);
    }
    *out = (hal_drive_status_t){
        .enabled = d->have_heartbeat && d->hb.axis_state == HAL_ODRIVE_AXIS_STATE_CLOSED_LOOP,
        .fault = d->have_heartbeat && d->hb.axis_error != 0u,
        .fault_code = d->hb.axis_error,
        .bus_voltage_v = d->bus_voltage_v,
        .temperature_c = d->temperature_c,
        .current_a = d->iq_measured_a,
        .age_ticks = d->have_heartbeat ? d->age_ticks : UINT32_MAX,
    };
    return HAL_OK;
}

void hal_odrive_bind(hal_odrive_t *d, hal_t *hal)
{
    hal->actuator = (hal_actuator_t){d, od_enable, od_command, od_status};
}
