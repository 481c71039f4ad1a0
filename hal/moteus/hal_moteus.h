/*
 * hal_moteus: a moteus controller (register protocol over CAN-FD) as the
 * actuator part of an hal_t (issue 23): torque only, as position mode with
 * no position or velocity target and kp = kd = 0 (kp_scale = kd_scale = 0),
 * the torque as feed-forward; each command also queries mode, position,
 * velocity, torque, voltage, temperature and fault (moteus's default query).
 *   enable(true)        nothing on the wire: the first command enters
 *                       position mode; enable(false) sends the stop command
 *   command_current(i)  position mode, feed-forward torque i kt (motor N m)
 *   status              the replies read from the bus: mode 1 (fault) or a
 *                       fault code is a fault; voltage, temperature
 * moteus needs CAN-FD (a command with its query is 32 bytes): the STM32F4's
 * bxCAN cannot carry it; a board with FDCAN, or SocketCAN on a host.
 * Identifier: 0x8000 (reply wanted) | source << 8 | destination, 29-bit.
 * tests/hal checks the bytes against the moteus package's own encoder and
 * parser.  Pure memory, bounded; builds for the MCU.
 */
#ifndef HAL_MOTEUS_H
#define HAL_MOTEUS_H

#include <stdbool.h>
#include <stddef.h>
#include <stdint.h>

#include "hal.h"

#ifdef __cplusplus
extern "C" {
#endif

#define HAL_MOTEUS_MODE_STOPPED 0u
#define HAL_MOTEUS_MODE_FAULT 1u
#define HAL_MOTEUS_MODE_POSITION 10u
#define HAL_MOTEUS_RX_PER_CALL 4u

/* What a reply carried (fields not in it keep their previous values). */
typedef struct {
    bool have_mode;
    uint8_t mode;
    uint32_t fault;
    float position_rev;
    float velocity_rev_s;
    float torque_nm;
    float voltage_v;
    float temperature_c;
} hal_moteus_reply_t;

/* The register bytes of a torque-only position command (+ the default
 * query), and of a stop; return the length (0 when cap is too small). */
size_t hal_moteus_encode_torque(float torque_nm, bool query, uint8_t *buf, size_t cap);
size_t hal_moteus_encode_stop(uint8_t *buf, size_t cap);
/* An FD frame of those bytes, padded with 0x50 (NOP) to a CAN-FD length. */
int hal_moteus_frame(uint8_t dest, uint8_t source, bool reply, const uint8_t *buf, size_t n,
                     hal_can_frame_t *f);
/* Parses reply subframes; HAL_OK, or HAL_ERR_FORMAT at the first byte it
 * cannot read (what came before it is kept). */
int hal_moteus_parse_reply(const uint8_t *buf, size_t n, hal_moteus_reply_t *out);

typedef struct {
    const hal_can_t *bus;
    uint8_t dest;               /* the moteus id */
    uint8_t source;             /* ours */
    float kt_nm_per_a;
    bool enabled;
    hal_moteus_reply_t last;
    uint32_t age_ticks;
} hal_moteus_t;

void hal_moteus_init(hal_moteus_t *d, const hal_can_t *bus, uint8_t dest, uint8_t source,
                     float kt_nm_per_a);
void hal_moteus_bind(hal_moteus_t *d, hal_t *hal);

#ifdef __cplusplus
}
#endif

#endif /* HAL_MOTEUS_H */
