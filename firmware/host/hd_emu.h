/*
 * hd_emu: the whole joint in a box, for host tests of the CAN tools.
 *
 * The real firmware (hd_fw) on the mock HAL's CAN and NVM, fed by the
 * simulated joint (sim/, hal/sim), behind a small C API that a Python
 * wrapper (tools/hdtools/emu.py) drives through ctypes and attaches to a
 * python-can bus.  Nothing of the firmware is re-implemented: frames go in
 * through the HAL's receive queue and come out of its transmitter.
 *
 * Time is the emulator's: tick k happens at t_us = k * 1000 from creation,
 * across reboots (a transmitted frame carries the time of the tick that
 * sent it).  A REBOOT command, or hd_emu_power_cycle, re-initialises the
 * firmware with the NVM bytes kept, as a real board restarting; the
 * simulated joint keeps turning.
 *
 * Host only (heap, libm).  One emulator is not thread-safe: one caller.
 */
#ifndef HD_EMU_H
#define HD_EMU_H

#include <stddef.h>
#include <stdint.h>

#ifdef __cplusplus
extern "C" {
#endif

typedef struct hd_emu hd_emu_t;

/* One CAN frame of at most 8 data bytes (HAL_CAN_FLAG_* in flags). */
typedef struct {
    uint64_t t_us;
    uint32_t id;
    uint8_t flags;
    uint8_t len;
    uint8_t data[8];
} hd_emu_frame_t;

/* Creates a joint.  scenario_text: a sim scenario (sim/scenarios/NAME.ini
 * syntax) on top of the paper's drive, NULL for the defaults.
 * config_text: firmware configuration text (docs/design/firmware.md) on top of the
 * firmware defaults and the scenario's sensor constants, NULL for none:
 * these are the "factory defaults" a boot without a saved configuration
 * runs.  The scenario's nominal calibration is stored in NVM.  Returns NULL
 * with a message in err on bad input. */
hd_emu_t *hd_emu_create(const char *scenario_text, const char *config_text, char *err,
                        size_t err_len);
void hd_emu_destroy(hd_emu_t *emu);

/* A joint with a drive: the dynamic joint (sim/hd_sim_joint's defaults, a
 * horizontal link: no payload, no gravity) behind the sensors and the
 * simulated drive (hal/simdrive) as the actuator, so the firmware closes
 * its control loop (issue 23).  The firmware is told its own defaults and
 * the gauge's nominal calibration (stored in NVM), never the plant.  The
 * output starts free; hd_emu_set_environment changes what it meets.
 * config_text as for hd_emu_create.  Never ends. */
hd_emu_t *hd_emu_create_dynamic(const char *config_text, char *err, size_t err_len);

/* What the output of a dynamic joint meets from the next tick on: a spring
 * to angle 0 (stiffness, damping; 0, 0: free) and a person's torque.
 * Returns 0, or -1 for a joint without dynamics or a non-finite or
 * negative value. */
int hd_emu_set_environment(hd_emu_t *emu, double stiffness_nm_rad, double damping_nm_s_rad,
                           double person_torque_nm);

/* The simulation's truth at the end of the last tick (dynamic joint). */
typedef struct {
    double t_s;
    double output_torque_nm;      /* the true flexspline torque */
    double motor_torque_nm;       /* what the drive applied */
    double person_torque_nm;
    double output_angle_rad;
    double output_velocity_rad_s;
    double drive_current_a;       /* the motor's q-axis current */
} hd_emu_truth_t;

/* Returns 0 with *out filled, or -1 for a joint without dynamics. */
int hd_emu_truth(const hd_emu_t *emu, hd_emu_truth_t *out);

/* Runs up to n ticks (ISR then background each); frames queued with
 * hd_emu_push_rx reach the firmware's receive queue as it has room.
 * Returns the ticks run (fewer when the scenario ended). */
uint32_t hd_emu_tick(hd_emu_t *emu, uint32_t n);

/* Queues a frame for the firmware (len <= 8).  Returns 0, or -1 if the
 * queue (HD_EMU_RX_CAP frames) is full or the frame is too long. */
int hd_emu_push_rx(hd_emu_t *emu, const hd_emu_frame_t *frame);

/* Takes the oldest transmitted frame.  Returns 1 with *out filled, 0 if
 * none is waiting. */
int hd_emu_pop_tx(hd_emu_t *emu, hd_emu_frame_t *out);

/* Frames lost because nobody popped them (the transmit ring was full). */
uint64_t hd_emu_tx_lost(const hd_emu_t *emu);

/* Restarts the firmware keeping the NVM bytes; reset_cause is HAL_RESET_*.
 * Returns 0 or -1 (the firmware refused to start: err). */
int hd_emu_power_cycle(hd_emu_t *emu, uint32_t reset_cause);

/* The NVM bytes (read and write: tests corrupt records here). */
uint8_t *hd_emu_nvm(hd_emu_t *emu, size_t *size);

uint64_t hd_emu_ticks(const hd_emu_t *emu);   /* since creation */
uint32_t hd_emu_boots(const hd_emu_t *emu);   /* 1 after creation */
int hd_emu_ended(const hd_emu_t *emu);        /* the scenario ran out */

#ifdef __cplusplus
}
#endif

#endif /* HD_EMU_H */
