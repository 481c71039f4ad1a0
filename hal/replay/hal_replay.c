/* hal_replay: see hal_replay.h (host only). */
#include "hal_replay.h"

#include <stdio.h>
#include <stdlib.h>
#include <string.h>

#include "hd_rawstream.h"

struct hal_replay {
    FILE *f;
    uint32_t ts_us;
    uint16_t record_size;
    uint64_t records;
    uint64_t pos;          /* records consumed */
    uint32_t trailing;
    hal_adc_sample_t adc;
    hal_encoder_sample_t enc;
    int enc_rc;
};

static hal_replay_t *fail(FILE *f, hal_replay_t *r, char *err, size_t errlen, const char *path,
                          const char *why)
{
    if (err != NULL && errlen > 0u) {
        snprintf(err, errlen, "%s: %s", path, why);
    }
    if (f != NULL) {
        fclose(f);
    }
    free(r);
    return NULL;
}

hal_replay_t *hal_replay_open(const char *path, char *err, size_t errlen)
{
    FILE *f = fopen(path, "rb");
    if (f == NULL) {
        return fail(NULL, NULL, err, errlen, path, "cannot open");
    }
    uint8_t h[HAL_REPLAY_HEADER_BYTES];
    if (fread(h, 1, sizeof h, f) != sizeof h) {
        return fail(f, NULL, err, errlen, path, "shorter than the 16-byte header");
    }
    hd_raw_header_t hdr;
    const hd_raw_err_t herr = hd_raw_header_parse(h, &hdr);
    if (herr != HD_RAW_OK) {
        return fail(f, NULL, err, errlen, path, hd_raw_err_str(herr));
    }
    const uint16_t rs = hdr.record_size;
    if (fseek(f, 0, SEEK_END) != 0) {
        return fail(f, NULL, err, errlen, path, "cannot seek");
    }
    long size = ftell(f);
    if (size < (long)HAL_REPLAY_HEADER_BYTES || fseek(f, HAL_REPLAY_HEADER_BYTES, SEEK_SET) != 0) {
        return fail(f, NULL, err, errlen, path, "cannot seek");
    }
    hal_replay_t *r = calloc(1, sizeof *r);
    if (r == NULL) {
        return fail(f, NULL, err, errlen, path, "out of memory");
    }
    r->f = f;
    r->ts_us = hdr.ts_us;
    r->record_size = rs;
    uint64_t body = (uint64_t)size - HAL_REPLAY_HEADER_BYTES;
    r->records = body / rs;
    r->trailing = (uint32_t)(body % rs);
    return r;
}

static int adc_read(void *ctx, hal_adc_sample_t *out)
{
    hal_replay_t *r = ctx;
    if (r->pos >= r->records) {
        return HAL_ERR_END;
    }
    uint8_t rec[HAL_REPLAY_RECORD_BYTES];
    if (fread(rec, 1, sizeof rec, r->f) != sizeof rec ||
        (r->record_size > HAL_REPLAY_RECORD_BYTES &&
         fseek(r->f, (long)(r->record_size - HAL_REPLAY_RECORD_BYTES), SEEK_CUR) != 0)) {
        r->pos = r->records; /* stop: the file changed under us */
        r->enc_rc = HAL_ERR_IO;
        return HAL_ERR_IO;
    }
    r->pos++;
    hd_raw_record_decode(rec, &r->adc, &r->enc);
    r->enc_rc = HAL_OK;
    *out = r->adc;
    return HAL_OK;
}

static int encoder_read(void *ctx, hal_encoder_sample_t *out)
{
    hal_replay_t *r = ctx;
    *out = r->enc;
    return r->enc_rc;
}

static uint64_t time_us(void *ctx)
{
    const hal_replay_t *r = ctx;
    return r->pos * r->ts_us; /* time of the record the next adc_read returns */
}

void hal_replay_bind(hal_replay_t *r, hal_t *hal)
{
    hal->sensors.ctx = r;
    hal->sensors.adc_read = adc_read;
    hal->sensors.encoder_read = encoder_read;
    hal->clock.ctx = r;
    hal->clock.time_us = time_us;
}

uint32_t hal_replay_ts_us(const hal_replay_t *r)
{
    return r->ts_us;
}

uint64_t hal_replay_record_count(const hal_replay_t *r)
{
    return r->records;
}

uint64_t hal_replay_position(const hal_replay_t *r)
{
    return r->pos;
}

uint32_t hal_replay_trailing_bytes(const hal_replay_t *r)
{
    return r->trailing;
}

void hal_replay_close(hal_replay_t *r)
{
    if (r != NULL) {
        fclose(r->f);
        free(r);
    }
}
