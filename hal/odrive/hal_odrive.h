/*
 * hal_odrive: an ODrive on CAN ("CAN Simple", firmware 0.5.6 / 0.6.x) as the
 * actuator part of an hal_t (issue 23), for a team that pairs this board
 * with a drive it already owns.  On the STM32F4 it sits on CAN2 (or on the
 * joint's bus with its own 11-bit ids: identifier = node << 5 | command,
 * no clash with this protocol's 29-bit ids).
 *   enable(true)        Clear_Errors, then Set_Controller_Mode (torque
 *                       control, passthrough input), Set_Axis_State
 *                       CLOSED_LOOP_CONTROL; enable(false) Set_Axis_State IDLE
 *   command_current(i)  Set_Input_Torque(i kt): the ODrive takes motor N m;
 *                       sent every tick, so the ODrive's own axis watchdog
 *                       (config.enable_watchdog, fed by the frames it
 *                       receives for the axis) disarms it when the stream
 *                       stops; not verified against a real ODrive
 *   status              the latest Heartbeat (axis error, state) and
 *                       Get_Bus_Voltage_Current / Get_Iq / Get_Temperature
 *                       frames, read from the bus without waiting
 * Layouts: ODrive's published CAN Simple DBC; tests/hal checks these bytes
 * against the odrive-can package's DBC through cantools.
 * Pure memory: no heap, bounded (at most HAL_ODRIVE_RX_PER_CALL frames read
 * per status call); builds for the MCU.
 */
#ifndef HAL_ODRIVE_H
#define HAL_ODRIVE_H

#include <stdbool.h>
#include <stdint.h>

#include "hal.h"

#ifdef __cplusplus
extern "C" {
#endif

/* CAN Simple command ids (low 5 bits of the identifier). */
#define HAL_ODRIVE_CMD_HEARTBEAT 0x01u
#define HAL_ODRIVE_CMD_SET_AXIS_STATE 0x07u
#define HAL_ODRIVE_CMD_SET_CONTROLLER_MODE 0x0Bu
#define HAL_ODRIVE_CMD_SET_INPUT_TORQUE 0x0Eu
#define HAL_ODRIVE_CMD_GET_IQ 0x14u
#define HAL_ODRIVE_CMD_GET_TEMPERATURE 0x15u
#define HAL_ODRIVE_CMD_GET_BUS_VOLTAGE_CURRENT 0x17u
#define HAL_ODRIVE_CMD_CLEAR_ERRORS 0x18u

#define HAL_ODRIVE_AXIS_STATE_IDLE 1u
#define HAL_ODRIVE_AXIS_STATE_CLOSED_LOOP 8u
#define HAL_ODRIVE_CONTROL_MODE_TORQUE 1u
#define HAL_ODRIVE_INPUT_MODE_PASSTHROUGH 1u

#define HAL_ODRIVE_RX_PER_CALL 4u

typedef struct {
    uint32_t axis_error;
    uint8_t axis_state;
    uint8_t procedure_result;
    bool trajectory_done;
} hal_odrive_heartbeat_t;

/* Frame codecs (node 0..63). */
void hal_odrive_encode_set_axis_state(uint8_t node, uint32_t state, hal_can_frame_t *f);
void hal_odrive_encode_set_controller_mode(uint8_t node, uint32_t control_mode,
                                           uint32_t input_mode, hal_can_frame_t *f);
void hal_odrive_encode_set_input_torque(uint8_t node, float torque_nm, hal_can_frame_t *f);
void hal_odrive_encode_clear_errors(uint8_t node, hal_can_frame_t *f);
/* HAL_OK, or HAL_ERR_FORMAT for another command, a 29-bit id or a short frame. */
int hal_odrive_decode_heartbeat(const hal_can_frame_t *f, hal_odrive_heartbeat_t *out);

typedef struct {
    const hal_can_t *bus;       /* the bus the ODrive is on (CAN2) */
    uint8_t node;               /* its axis node id */
    float kt_nm_per_a;          /* current -> torque for Set_Input_Torque */
    bool enabled;
    bool have_heartbeat;
    hal_odrive_heartbeat_t hb;
    uint32_t age_ticks;         /* status calls since the last heartbeat */
    float bus_voltage_v;
    float iq_measured_a;
    float temperature_c;
} hal_odrive_t;

void hal_odrive_init(hal_odrive_t *d, const hal_can_t *bus, uint8_t node, float kt_nm_per_a);
/* Fills hal->actuator only. */
void hal_odrive_bind(hal_odrive_t *d, hal_t *hal);

#ifdef __cplusplus
}
#endif

#endif /* HAL_ODRIVE_H */
