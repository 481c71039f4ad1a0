/*
 * hal_semihost: HAL backends over ARM semihosting, for the Cortex-M4 image
 * running in QEMU (firmware/board/mps2_an386).  No heap, no libc.
 *
 * - hal_sh_stream_t: the sensors part (and a sample clock) from a raw sample
 *   stream on the host (.hdraw, docs/reference/raw-stream.md): semihosting supplies
 *   the bytes, hd_rawstream's reader (the same as the host's hal/replay)
 *   reads the format.
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
#include "hd_rawstream.h"

#ifdef __cplusplus
extern "C" {
#endif

typedef struct {
    int fd;
    hd_raw_reader_t reader;
} hal_sh_stream_t;

/* Opens the host file and checks the header.  Returns HAL_OK, HAL_ERR_IO
 * (the host could not open or read it) or HAL_ERR_FORMAT; s->reader.why
 * says why. */
int hal_sh_stream_open(hal_sh_stream_t *s, const char *path);
/* Points hal's sensors and clock parts at the stream. */
void hal_sh_stream_bind(hal_sh_stream_t *s, hal_t *hal);
void hal_sh_stream_close(hal_sh_stream_t *s);

#define HAL_SH_WRITER_BUF 8192u

typedef struct {
    int fd;
    uint8_t buf[HAL_SH_WRITER_BUF];
    uint32_t len;
    uint32_t dropped_bytes;   /* appends that did not fit */
    uint32_t io_errors;
} hal_sh_writer_t;

/* Creates (truncates) a host file; returns HAL_OK or HAL_ERR_IO. */
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
