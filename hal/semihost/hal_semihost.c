/* hal_semihost: see hal_semihost.h. */
#include "hal_semihost.h"

#include <string.h>

#include "hal_mock.h"
#include "hd_rawstream.h"
#include "semihost.h"

#define HEADER_BYTES 16u

const char *hal_sh_err_str(int err)
{
    switch (err) {
    case HAL_SH_OK: return "ok";
    case HAL_SH_ERR_OPEN: return "cannot open";
    case HAL_SH_ERR_HEADER: return "shorter than the 16-byte header";
    case HAL_SH_ERR_MAGIC: return "not a raw sample stream (magic is not HDRW)";
    case HAL_SH_ERR_VERSION: return "unsupported version (expected 1)";
    case HAL_SH_ERR_RECORD: return "record size outside 16..256 bytes";
    case HAL_SH_ERR_TS: return "sample period ts_us is 0";
    default: return "unknown error";
    }
}

/* The board's exit codes distinguish these, so keep its own error enum. */
static int stream_err(hd_raw_err_t err)
{
    switch (err) {
    case HD_RAW_OK: return HAL_SH_OK;
    case HD_RAW_ERR_MAGIC: return HAL_SH_ERR_MAGIC;
    case HD_RAW_ERR_VERSION: return HAL_SH_ERR_VERSION;
    case HD_RAW_ERR_RECORD: return HAL_SH_ERR_RECORD;
    default: return HAL_SH_ERR_TS;
    }
}

int hal_sh_stream_open(hal_sh_stream_t *s, const char *path)
{
    memset(s, 0, sizeof *s);
    s->fd = sh_open(path, SH_MODE_RB);
    if (s->fd < 0) {
        return HAL_SH_ERR_OPEN;
    }
    uint8_t h[HEADER_BYTES];
    hd_raw_header_t hdr = {0};
    long size = sh_flen(s->fd);
    int rc = HAL_SH_OK;
    if (size < (long)HEADER_BYTES || sh_read(s->fd, h, sizeof h) != (long)sizeof h) {
        rc = HAL_SH_ERR_HEADER;
    } else {
        rc = stream_err(hd_raw_header_parse(h, &hdr));
    }
    if (rc != HAL_SH_OK) {
        (void)sh_close(s->fd);
        s->fd = -1;
        return rc;
    }
    s->record_size = hdr.record_size;
    s->ts_us = hdr.ts_us;
    uint32_t body = (uint32_t)size - HEADER_BYTES;
    s->records = body / s->record_size;
    s->trailing = body % s->record_size;
    return HAL_SH_OK;
}

/* Refills buf with whole records; false at the end of the data or on error. */
static bool refill(hal_sh_stream_t *s)
{
    uint64_t left = s->records - s->pos;
    uint32_t per_chunk = HAL_SH_STREAM_BUF / s->record_size;
    uint32_t n = left < per_chunk ? (uint32_t)left : per_chunk;
    uint32_t want = n * s->record_size;
    long got = sh_read(s->fd, s->buf, want);
    s->buf_off = 0;
    s->buf_len = got > 0 ? (uint32_t)got : 0u;
    if (got != (long)want || want == 0u) {
        s->io_errors++;
        return false;
    }
    return true;
}

static int adc_read(void *ctx, hal_adc_sample_t *out)
{
    hal_sh_stream_t *s = ctx;
    if (s->fd < 0 || s->pos >= s->records) {
        return HAL_ERR_END;
    }
    if (s->buf_off + s->record_size > s->buf_len && !refill(s)) {
        s->pos = s->records; /* stop: the file changed under us */
        s->enc_rc = HAL_ERR_IO;
        return HAL_ERR_IO;
    }
    const uint8_t *rec = &s->buf[s->buf_off];
    s->buf_off += s->record_size;
    s->pos++;
    hd_raw_record_decode(rec, &s->adc, &s->enc);
    s->enc_rc = HAL_OK;
    *out = s->adc;
    return HAL_OK;
}

static int encoder_read(void *ctx, hal_encoder_sample_t *out)
{
    const hal_sh_stream_t *s = ctx;
    *out = s->enc;
    return s->enc_rc;
}

static uint64_t time_us(void *ctx)
{
    const hal_sh_stream_t *s = ctx;
    return s->pos * s->ts_us; /* time of the record the next adc_read returns */
}

void hal_sh_stream_bind(hal_sh_stream_t *s, hal_t *hal)
{
    hal->sensors.ctx = s;
    hal->sensors.adc_read = adc_read;
    hal->sensors.encoder_read = encoder_read;
    hal->clock.ctx = s;
    hal->clock.time_us = time_us;
}

void hal_sh_stream_close(hal_sh_stream_t *s)
{
    if (s->fd >= 0) {
        (void)sh_close(s->fd);
        s->fd = -1;
    }
}

int hal_sh_writer_open(hal_sh_writer_t *w, const char *path)
{
    memset(w, 0, sizeof *w);
    w->fd = sh_open(path, SH_MODE_WB);
    return w->fd >= 0 ? HAL_SH_OK : HAL_SH_ERR_OPEN;
}

int hal_sh_writer_append(hal_sh_writer_t *w, const void *data, size_t len)
{
    if (len > HAL_SH_WRITER_BUF - w->len) {
        w->dropped_bytes += (uint32_t)len;
        return HAL_ERR_BUSY;
    }
    memcpy(&w->buf[w->len], data, len);
    w->len += (uint32_t)len;
    return HAL_OK;
}

int hal_sh_writer_flush(hal_sh_writer_t *w)
{
    int rc = HAL_OK;
    if (w->len > 0u && (w->fd < 0 || sh_write(w->fd, w->buf, w->len) != 0)) {
        w->io_errors++;
        rc = HAL_ERR_IO;
    }
    w->len = 0;
    return rc;
}

int hal_sh_writer_close(hal_sh_writer_t *w)
{
    int rc = hal_sh_writer_flush(w);
    if (w->fd >= 0) {
        (void)sh_close(w->fd);
        w->fd = -1;
    }
    return rc;
}

void hal_sh_canlog_hook(void *ctx, const hal_can_frame_t *frame, uint64_t t_us)
{
    char line[200];
    int n = hal_candump_format(frame, t_us, "vcan0", line, sizeof line);
    if (n > 0) {
        (void)hal_sh_writer_append(ctx, line, (size_t)n);
    }
}
