/*
 * hd_rawstream: the .hdraw raw sample stream (docs/reference/raw-stream.md), and the
 * one reader of it.  Pure: no I/O of its own, no heap, builds for host and
 * MCU.  The bytes come from a caller's callback (a file on the host, ARM
 * semihosting in the QEMU image), so every reader shares this code.
 *
 * The reader is a HAL sensors + clock source: each adc_read takes the next
 * record (HAL_ERR_END after the last whole one; a partial last record is
 * ignored and counted), encoder_read returns that record's encoder part,
 * time_us = records consumed x ts_us.
 */
#ifndef HD_RAWSTREAM_H
#define HD_RAWSTREAM_H

#include <stddef.h>
#include <stdint.h>

#include "hal.h"

#ifdef __cplusplus
extern "C" {
#endif

#define HD_RAW_HEADER_BYTES 16u
#define HD_RAW_RECORD_BYTES 16u      /* fields this version defines */
#define HD_RAW_RECORD_MAX_BYTES 256u /* larger records (future fields) are refused */
#define HD_RAW_VERSION 1u
#define HD_RAW_READ_BUF 4096u        /* bytes fetched per callback */

#define HD_RAW_FLAG_SATURATED 0x1u
#define HD_RAW_FLAG_ENC_FAULT 0x2u
#define HD_RAW_FLAG_HAS_OUTPUT 0x4u

/* Reads up to len bytes at the current position; returns the count read
 * (less only at the end) or a negative value on error. */
typedef long (*hd_raw_source_fn)(void *ctx, void *buf, size_t len);

typedef struct {
    hd_raw_source_fn read;
    void *ctx;
    uint32_t ts_us;
    uint32_t record_size;
    uint64_t records;           /* whole records in the stream */
    uint64_t pos;               /* records consumed */
    uint32_t trailing;          /* bytes of a partial last record (ignored) */
    uint8_t buf[HD_RAW_READ_BUF];
    uint32_t buf_len;
    uint32_t buf_off;
    hal_adc_sample_t adc;
    hal_encoder_sample_t enc;
    int enc_rc;
    uint32_t io_errors;
    const char *why;            /* the reason of the last failure, static */
} hd_raw_reader_t;

/* Reads and checks the 16-byte header of a stream of total_bytes bytes.
 * Returns HAL_OK, HAL_ERR_IO (the source failed) or HAL_ERR_FORMAT (short,
 * wrong magic, version, record size or period); r->why says which. */
int hd_raw_reader_open(hd_raw_reader_t *r, hd_raw_source_fn read, void *ctx,
                       uint64_t total_bytes);
/* Points hal's sensors and clock parts at the reader. */
void hd_raw_reader_bind(hd_raw_reader_t *r, hal_t *hal);

/* Decodes the first HD_RAW_RECORD_BYTES of a record. */
void hd_raw_record_decode(const uint8_t *record, hal_adc_sample_t *adc,
                          hal_encoder_sample_t *enc);

#ifdef __cplusplus
}
#endif

#endif /* HD_RAWSTREAM_H */
