/*
 * hd_rawstream: the .hdraw raw sample stream (docs/raw-stream.md) as bytes.
 * Pure: no I/O, no heap, builds for host and MCU.  Every reader of the
 * format (hal/replay on the host, hal/semihost in the QEMU image) decodes
 * through here, so they cannot disagree.
 */
#ifndef HD_RAWSTREAM_H
#define HD_RAWSTREAM_H

#include <stdint.h>

#include "hal.h"

#ifdef __cplusplus
extern "C" {
#endif

#define HD_RAW_HEADER_BYTES 16u
#define HD_RAW_RECORD_BYTES 16u      /* fields this version defines */
#define HD_RAW_RECORD_MAX_BYTES 256u /* larger records (future fields) are refused */
#define HD_RAW_VERSION 1u

#define HD_RAW_FLAG_SATURATED 0x1u
#define HD_RAW_FLAG_ENC_FAULT 0x2u
#define HD_RAW_FLAG_HAS_OUTPUT 0x4u

typedef enum {
    HD_RAW_OK = 0,
    HD_RAW_ERR_MAGIC = -1,   /* magic is not HDRW */
    HD_RAW_ERR_VERSION = -2, /* version is not 1 */
    HD_RAW_ERR_RECORD = -3,  /* record size outside [16, 256] */
    HD_RAW_ERR_TS = -4,      /* sample period 0 */
} hd_raw_err_t;

typedef struct {
    uint16_t record_size;
    uint32_t ts_us;
} hd_raw_header_t;

/* Checks a 16-byte header; fills out on success. */
hd_raw_err_t hd_raw_header_parse(const uint8_t *header, hd_raw_header_t *out);

/* The reason for an hd_raw_err_t, as a static string. */
const char *hd_raw_err_str(int err);

/* Decodes the first HD_RAW_RECORD_BYTES of a record. */
void hd_raw_record_decode(const uint8_t *record, hal_adc_sample_t *adc,
                          hal_encoder_sample_t *enc);

#ifdef __cplusplus
}
#endif

#endif /* HD_RAWSTREAM_H */
