/*
 * hal: everything the 1 kHz ISR touches, as one small interface.
 *
 * A backend fills one or more parts of an hal_t (sensors, can, nvm, clock,
 * system, actuator)
 * with its context and function pointers.  Backends live in their own
 * folders (hal/mock, hal/sim, hal/replay, hal/socketcan, and the MCU ports).
 * Firmware checks for NULL before calling a part.
 *
 * Rules for every function called from the ISR (sensors, can, clock, actuator):
 * non-blocking, bounded time, no allocation.
 * Return codes: 0 = ok, negative = hal_err_t.
 */
#ifndef HAL_H
#define HAL_H

#include <stdbool.h>
#include <stddef.h>
#include <stdint.h>

#ifdef __cplusplus
extern "C" {
#endif

typedef enum {
    HAL_OK = 0,
    HAL_ERR_NO_DATA = -1,    /* nothing available (empty receive, end of replay) */
    HAL_ERR_BUSY = -2,       /* transmit queue full: frame not queued */
    HAL_ERR_FAULT = -3,      /* the device reported a fault (open bridge, bus-off, ...) */
    HAL_ERR_RANGE = -4,      /* argument out of range (NVM offset, frame length) */
    HAL_ERR_IO = -5,         /* I/O error (host backends) */
    HAL_ERR_END = -6,        /* the sample source is exhausted (replay, sim end) */
    HAL_ERR_FORMAT = -7,     /* data not in the expected format (a .hdraw header) */
} hal_err_t;

#define HAL_CAN_MAX_DATA 64u
#define HAL_CAN_FLAG_EXT 0x01u  /* 29-bit identifier */
#define HAL_CAN_FLAG_FD  0x02u  /* CAN FD frame (len up to 64) */
#define HAL_CAN_FLAG_ERR 0x04u  /* error frame (receive only) */
#define HAL_CAN_FLAG_RTR 0x08u

typedef struct {
    uint32_t id;
    uint8_t len;
    uint8_t flags;
    uint8_t data[HAL_CAN_MAX_DATA];
} hal_can_frame_t;

typedef struct {
    int32_t bridge_counts;  /* signed ADC counts of the amplified bridge output */
    bool saturated;         /* the converter reported its rail (or counts at full scale) */
} hal_adc_sample_t;

typedef struct {
    uint32_t motor_counts;  /* free-running counter, wraps modulo 2^32 */
    uint32_t output_counts; /* output-side encoder if present, wraps */
    bool has_output;        /* false: output angle = motor angle / gear ratio */
    bool fault;             /* encoder reported an error (lost signal, parity) */
} hal_encoder_sample_t;

typedef struct {
    float motor_current_a;  /* torque-producing (q-axis) motor current; + = + motor torque */
    bool fault;             /* the drive reported the reading unusable */
} hal_current_sample_t;

typedef struct {
    uint32_t can_tx_ok;
    uint32_t can_tx_dropped;   /* queue full */
    uint32_t can_rx;
    uint32_t can_error_frames;
    uint32_t can_bus_off;
    uint32_t can_rx_overruns;  /* frames the controller lost before they were read
                                  (a full receive FIFO); 0 where the backend cannot tell */
    uint32_t can_tx_aborted;   /* frames handed to the controller that it completed
                                  without sending; 0 where the backend cannot tell */
    uint32_t can_tx_error_count; /* the controller's transmit / receive error counters */
    uint32_t can_rx_error_count; /* (TEC, REC: 0..255) as last read; 0 where unknown */
} hal_counters_t;

/* The HAL is independent parts, each with its own context, so a
 * runner can compose them: e.g. sensors from the simulated joint, CAN from
 * SocketCAN, NVM from a file.  A part whose functions are NULL is absent. */

typedef struct {
    void *ctx;
    /* Called once per tick. */
    int (*adc_read)(void *ctx, hal_adc_sample_t *out);
    int (*encoder_read)(void *ctx, hal_encoder_sample_t *out);
    /* May be NULL (no current channel).  The motor current of this tick,
     * e.g. the drive's last q-axis current (docs/design/slow-torque.md). */
    int (*current_read)(void *ctx, hal_current_sample_t *out);
} hal_sensors_t;

typedef struct {
    void *ctx;
    /* Non-blocking.  send returns HAL_ERR_BUSY when the queue is full;
     * recv returns HAL_ERR_NO_DATA when nothing is waiting. */
    int (*send)(void *ctx, const hal_can_frame_t *frame);
    int (*recv)(void *ctx, hal_can_frame_t *frame);
    void (*counters)(void *ctx, hal_counters_t *out); /* may be NULL */
    /* May be NULL.  Accept only these identifiers (HAL_CAN_ID_EXT_BIT set
     * for 29-bit ones) from now on; n == 0 accepts everything.  Called from
     * the firmware's background context when its node id changes, never
     * from the ISR.  Returns HAL_OK or HAL_ERR_RANGE (too many ids). */
    int (*set_rx_filter)(void *ctx, const uint32_t *ids, size_t n);
} hal_can_t;

/* In set_rx_filter's ids: the identifier is a 29-bit one. */
#define HAL_CAN_ID_EXT_BIT 0x80000000u

typedef struct {
    void *ctx;
    /* Byte-addressed region of `size` bytes for the firmware's records (one
     * A/B store: copy A at offset 0, copy B at size/2; each half is erased
     * as a whole, so on flash each half is one erase unit).  erase sets a
     * range to 0xFF (flash semantics); a write may be interrupted at any
     * byte by power loss.  Called from the background context only. */
    size_t size;
    int (*read)(void *ctx, size_t offset, void *buf, size_t len);
    int (*write)(void *ctx, size_t offset, const void *buf, size_t len);
    int (*erase)(void *ctx, size_t offset, size_t len);
} hal_nvm_t;

typedef struct {
    void *ctx;
    uint64_t (*time_us)(void *ctx); /* monotonic microseconds */
} hal_clock_t;

/* Why the MCU last started (bits; several may be set). */
#define HAL_RESET_POWER_ON 0x01u
#define HAL_RESET_PIN      0x02u
#define HAL_RESET_SOFTWARE 0x04u  /* the firmware's REBOOT command */
#define HAL_RESET_WATCHDOG 0x08u
#define HAL_RESET_BROWNOUT 0x10u
#define HAL_RESET_LOCKUP   0x20u
#define HAL_RESET_CLOCK    0x40u  /* the clock tree fell back (e.g. HSE never ready) */

/* What the board knows about the previous run, read once at boot. */
typedef struct {
    uint32_t reset_cause;   /* HAL_RESET_* */
    bool fault_valid;       /* a HardFault record survived the reset */
    uint32_t fault_pc;      /* stacked PC of the faulting instruction */
    uint32_t fault_lr;      /* stacked LR */
    uint32_t fault_cfsr;    /* SCB->CFSR (configurable fault status) */
    uint32_t fault_hfsr;    /* SCB->HFSR */
    uint32_t fault_addr;    /* SCB->BFAR or MMFAR when valid, else 0 */
    uint32_t init_errors;   /* board-specific bits of drivers that failed to start at
                               this boot (0: all started; e.g. STM32_BOARD_INIT_*) */
} hal_boot_info_t;

typedef struct {
    void *ctx;
    uint32_t board_id;      /* four characters, little-endian ("HOST", "F405", ...) */
    /* May be NULL.  Fills *out; the board clears its fault record after the
     * first call, so a fault is reported once. */
    void (*boot_info)(void *ctx, hal_boot_info_t *out);
    /* May be NULL (no reboot).  Restarts the MCU (does not return there); a
     * host runner re-initialises the firmware instead.  Background only. */
    void (*reboot)(void *ctx);
} hal_system_t;

/* What a motor drive reports about itself (hal_actuator_t.status). */
typedef struct {
    bool enabled;           /* its output stage is on */
    bool fault;             /* it reported a fault: it will not (or must not) drive */
    uint32_t fault_code;    /* the drive's own code (0: none; ODrive axis error, moteus fault) */
    float bus_voltage_v;    /* NaN where unknown */
    float temperature_c;    /* NaN where unknown */
    float current_a;        /* the q-axis current it measured; NaN where unknown */
    uint32_t age_ticks;     /* ticks since the drive last reported (0: this tick) */
} hal_drive_status_t;

/* The motor drive (issue 23).  May be absent (all NULL): the firmware then
 * refuses every control mode but STOP with a status.  Called from the tick:
 * non-blocking, bounded, no allocation.  The firmware calls enable(false)
 * or command_current once per tick with control on; a drive that hears
 * nothing for its own watchdog time must stop by itself. */
typedef struct {
    void *ctx;
    /* Output stage on (closed-loop current control) or off (coasting). */
    int (*enable)(void *ctx, bool on);
    /* This tick's q-axis current, A (+ = + motor torque).  The backend
     * saturates to what the drive can do; the firmware has already limited it. */
    int (*command_current)(void *ctx, float current_a);
    /* The drive's latest report, without waiting. */
    int (*status)(void *ctx, hal_drive_status_t *out);
} hal_actuator_t;

typedef struct {
    const char *name;
    hal_sensors_t sensors;
    hal_can_t can;
    hal_nvm_t nvm;
    hal_clock_t clock;
    hal_system_t system;
    hal_actuator_t actuator;
} hal_t;

#ifdef __cplusplus
}
#endif

#endif /* HAL_H */
