/* hd_rawstream: see hd_rawstream.h. */
#include "hd_rawstream.h"

#include <stdbool.h>
#include <string.h>

static uint32_t le32(const uint8_t *p)
{
    return (uint32_t)p[0] | ((uint32_t)p[1] << 8) | ((uint32_t)p[2] << 16) |
           ((uint32_t)p[3] << 24);
}

static uint16_t le16(const uint8_t *p)
{
    return (uint16_t)(p[0] | (p[1] << 8));
}

static int refuse(hd_raw_reader_t *r, int rc, const char *why)
{
    r->why = why;
    r->records = 0u;
    return rc;
}

int hd_raw_reader_open(hd_raw_reader_t *r, hd_raw_source_fn read, void *ctx,
                       uint64_t total_bytes)
{
    memset(r, 0, sizeof *r);
    r->read = read;
    r->ctx = ctx;
    r->why = "ok";
    uint8_t h[HD_RAW_HEADER_BYTES];
    if (total_bytes < HD_RAW_HEADER_BYTES) {
        return refuse(r, HAL_ERR_FORMAT, "shorter than the 16-byte header");
    }
    long got = read(ctx, h, sizeof h);
    if (got < 0) {
        return refuse(r, HAL_ERR_IO, "cannot read");
    }
    if (got != (long)sizeof h) {
        return refuse(r, HAL_ERR_FORMAT, "shorter than the 16-byte header");
    }
    if (memcmp(h, "HDRW", 4) != 0) {
        return refuse(r, HAL_ERR_FORMAT, "not a raw sample stream (magic is not HDRW)");
    }
    if (le16(&h[4]) != HD_RAW_VERSION) {
        return refuse(r, HAL_ERR_FORMAT, "unsupported version (expected 1)");
    }
    r->record_size = le16(&h[6]);
    if (r->record_size < HD_RAW_RECORD_BYTES || r->record_size > HD_RAW_RECORD_MAX_BYTES) {
        return refuse(r, HAL_ERR_FORMAT, "record size outside 16..256 bytes");
    }
    r->ts_us = le32(&h[8]);
    if (r->ts_us == 0u) {
        return refuse(r, HAL_ERR_FORMAT, "sample period ts_us is 0");
    }
    uint64_t body = total_bytes - HD_RAW_HEADER_BYTES;
    r->records = body / r->record_size;
    r->trailing = (uint32_t)(body % r->record_size);
    return HAL_OK;
}

/* Refills buf with whole records; false at the end of the data or on error. */
static bool refill(hd_raw_reader_t *r)
{
    uint64_t left = r->records - r->pos;
    uint32_t per_chunk = HD_RAW_READ_BUF / r->record_size;
    uint32_t n = left < per_chunk ? (uint32_t)left : per_chunk;
    uint32_t want = n * r->record_size;
    long got = r->read(r->ctx, r->buf, want);
    r->buf_off = 0;
    r->buf_len = got > 0 ? (uint32_t)got : 0u;
    if (got != (long)want || want == 0u) {
        r->io_errors++;
        r->why = "the stream ended early or could not be read";
        return false;
    }
    return true;
}

static int adc_read(void *ctx, hal_adc_sample_t *out)
{
    hd_raw_reader_t *r = ctx;
    if (r->pos >= r->records) {
        return HAL_ERR_END;
    }
    if (r->buf_off + r->record_size > r->buf_len && !refill(r)) {
        r->pos = r->records; /* stop: the file changed under us */
        r->enc_rc = HAL_ERR_IO;
        return HAL_ERR_IO;
    }
    const uint8_t *rec = &r->buf[r->buf_off];
    r->buf_off += r->record_size;
    r->pos++;
    hd_raw_record_decode(rec, &r->adc, &r->enc);
    r->enc_rc = HAL_OK;
    *out = r->adc;
    return HAL_OK;
}

static int encoder_read(void *ctx, hal_encoder_sample_t *out)
{
    const hd_raw_reader_t *r = ctx;
    *out = r->enc;
    return r->enc_rc;
}

static uint64_t time_us(void *ctx)
{
    const hd_raw_reader_t *r = ctx;
    return r->pos * r->ts_us; /* time of the record the next adc_read returns */
}

void hd_raw_reader_bind(hd_raw_reader_t *r, hal_t *hal)
{
    hal->sensors.ctx = r;
    hal->sensors.adc_read = adc_read;
    hal->sensors.encoder_read = encoder_read;
    hal->clock.ctx = r;
    hal->clock.time_us = time_us;
}

void hd_raw_record_decode(const uint8_t *record, hal_adc_sample_t *adc,
                          hal_encoder_sample_t *enc)
{
    const uint16_t flags = le16(&record[12]);
    adc->bridge_counts = (int32_t)le32(&record[0]);
    adc->saturated = (flags & HD_RAW_FLAG_SATURATED) != 0u;
    enc->motor_counts = le32(&record[4]);
    enc->output_counts = le32(&record[8]);
    enc->fault = (flags & HD_RAW_FLAG_ENC_FAULT) != 0u;
    enc->has_output = (flags & HD_RAW_FLAG_HAS_OUTPUT) != 0u;
}
