/*
 * hal_semihost: HAL backends over ARM semihosting, for the Cortex-M4 image
 * running in QEMU (firmware/board/mps2_an386).  No heap, no libc.
 *
 * - hal_sh_stream_t: the sensors part (and a sample clock) from a raw sample
 *   stream on the host (.hdraw, docs/raw-stream.md), read in chunks of
 *   HAL_SH_STREAM_BUF bytes.  Same semantics as the host's hal/replay: each
 *   adc_read takes the next record (HAL_ERR_END after the last), encoder_read
 *   returns that record's encoder part, time_us = records consumed x ts_us.
 * - hal_sh_writer_t: a buffered host file writer (binary dumps).
 * - hal_sh_canlog_hook: a hal_mock transmit hook that appends each frame as
 *   a `candump -l` line to a writer (interface "vcan0", like hdjoint-host).
 *
 * The writers never call the host from the hook: hal_sh_writer_flush does,
 * from the main loop.  A full buffer drops data and counts it.
 */
#ifndef HAL_SEMIHOST_H
#define HAL_SEMIHOST_H

#include <stdbool.h>
#include <stddef.h>
#include <stdint.h>

#include "hal.h"

#ifdef __cplusplus
extern "C" {
#endif

#define HAL_SH_STREAM_BUF 4096u
#define HAL_SH_RECORD_MIN 16u
#define HAL_SH_RECORD_MAX 256u

typedef enum {
    HAL_SH_OK = 0,
    HAL_SH_ERR_OPEN = -1,     /* the host could not open the file */
    HAL_SH_ERR_HEADER = -2,   /* shorter than the 16-byte header */
    HAL_SH_ERR_MAGIC = -3,    /* magic is not HDRW */
    HAL_SH_ERR_VERSION = -4,  /* version is not 1 */
    HAL_SH_ERR_RECORD = -5,   /* record size outside [16, 256] */
    HAL_SH_ERR_TS = -6,       /* sample period 0 */
} hal_sh_err_t;

typedef struct {
    int fd;
    uint32_t ts_us;
    uint32_t record_size;
    uint64_t records;         /* whole records in the file */
    uint64_t pos;             /* records consumed */
    uint32_t trailing;        /* bytes of a partial last record (ignored) */
    uint8_t buf[HAL_SH_STREAM_BUF];
    uint32_t buf_len;         /* valid bytes in buf */
    uint32_t buf_off;         /* next record's offset in buf */
    hal_adc_sample_t adc;
    hal_encoder_sample_t enc;
    int enc_rc;
    uint32_t io_errors;
} hal_sh_stream_t;

/* Opens and checks the header; returns HAL_SH_OK or a hal_sh_err_t. */
int hal_sh_stream_open(hal_sh_stream_t *s, const char *path);
/* Points hal's sensors and clock parts at the stream. */
void hal_sh_stream_bind(hal_sh_stream_t *s, hal_t *hal);
void hal_sh_stream_close(hal_sh_stream_t *s);
const char *hal_sh_err_str(int err);

#define HAL_SH_WRITER_BUF 8192u

typedef struct {
    int fd;
    uint8_t buf[HAL_SH_WRITER_BUF];
    uint32_t len;
    uint32_t dropped_bytes;   /* appends that did not fit */
    uint32_t io_errors;
} hal_sh_writer_t;

/* Creates (truncates) a host file; returns 0 or HAL_SH_ERR_OPEN. */
int hal_sh_writer_open(hal_sh_writer_t *w, const char *path);
/* Appends all len bytes or none; returns 0 or HAL_ERR_BUSY (counted). */
int hal_sh_writer_append(hal_sh_writer_t *w, const void *data, size_t len);
/* Writes the buffer to the host; returns 0 or HAL_ERR_IO. */
int hal_sh_writer_flush(hal_sh_writer_t *w);
int hal_sh_writer_close(hal_sh_writer_t *w);

/* hal_mock_tx_hook_t: ctx is a hal_sh_writer_t. */
void hal_sh_canlog_hook(void *ctx, const hal_can_frame_t *frame, uint64_t t_us);

#ifdef __cplusplus
}
#endif

#endif /* HAL_SEMIHOST_H */
