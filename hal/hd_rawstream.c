/* hd_rawstream: see hd_rawstream.h. */
#include "hd_rawstream.h"

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

hd_raw_err_t hd_raw_header_parse(const uint8_t *header, hd_raw_header_t *out)
{
    if (memcmp(header, "HDRW", 4) != 0) {
        return HD_RAW_ERR_MAGIC;
    }
    if (le16(&header[4]) != HD_RAW_VERSION) {
        return HD_RAW_ERR_VERSION;
    }
    const uint16_t record_size = le16(&header[6]);
    if (record_size < HD_RAW_RECORD_BYTES || record_size > HD_RAW_RECORD_MAX_BYTES) {
        return HD_RAW_ERR_RECORD;
    }
    const uint32_t ts_us = le32(&header[8]);
    if (ts_us == 0u) {
        return HD_RAW_ERR_TS;
    }
    out->record_size = record_size;
    out->ts_us = ts_us;
    return HD_RAW_OK;
}

const char *hd_raw_err_str(int err)
{
    switch (err) {
    case HD_RAW_OK: return "ok";
    case HD_RAW_ERR_MAGIC: return "not a raw sample stream (magic is not HDRW)";
    case HD_RAW_ERR_VERSION: return "unsupported version (expected 1)";
    case HD_RAW_ERR_RECORD: return "record size outside 16..256 bytes";
    case HD_RAW_ERR_TS: return "sample period ts_us is 0";
    default: return "unknown error";
    }
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
