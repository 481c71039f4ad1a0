/*
 * hal: everything the 1 kHz ISR touches, as one small interface.
 *
 * A backend fills an hal_t with its context and function pointers.  Backends
 * live in their own folders (hal/mock, hal/sim, hal/replay, hal/socketcan,
 * and the MCU ports).  A backend may leave CAN or NVM pointers NULL when it
 * does not provide them; firmware checks before calling.
 *
 * Rules for every function called from the ISR (adc_read, encoder_read,
 * can_send, can_recv, time_us): non-blocking, bounded time, no allocation.
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
    uint32_t can_tx_ok;
    uint32_t can_tx_dropped;   /* queue full */
    uint32_t can_rx;
    uint32_t can_error_frames;
    uint32_t can_bus_off;
} hal_counters_t;

typedef struct hal hal_t;
struct hal {
    void *ctx;
    const char *name;

    /* Sensors: called once per tick. */
    int (*adc_read)(void *ctx, hal_adc_sample_t *out);
    int (*encoder_read)(void *ctx, hal_encoder_sample_t *out);

    /* CAN: non-blocking.  can_recv returns HAL_ERR_NO_DATA when empty. */
    int (*can_send)(void *ctx, const hal_can_frame_t *frame);
    int (*can_recv)(void *ctx, hal_can_frame_t *frame);

    /* Monotonic microseconds since an arbitrary origin. */
    uint64_t (*time_us)(void *ctx);

    /* Non-volatile storage for the calibration record: byte-addressed region
     * of nvm_size bytes.  nvm_erase sets a range to 0xFF (flash semantics); a
     * write may be interrupted at any byte by power loss. */
    size_t nvm_size;
    int (*nvm_read)(void *ctx, size_t offset, void *buf, size_t len);
    int (*nvm_write)(void *ctx, size_t offset, const void *buf, size_t len);
    int (*nvm_erase)(void *ctx, size_t offset, size_t len);

    /* Backend counters (may be NULL). */
    void (*counters)(void *ctx, hal_counters_t *out);
};

#ifdef __cplusplus
}
#endif

#endif /* HAL_H */
