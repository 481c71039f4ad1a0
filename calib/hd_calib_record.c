/* Calibration record: encoding, and its place in the record store. */
#include "hd_calib_record.h"

#include <string.h>

#define OFF_MAGIC 0u
#define OFF_VERSION 4u
#define OFF_LENGTH 6u
#define OFF_SEQUENCE 8u
#define OFF_GAIN 12u
#define OFF_OFFSET 16u
#define OFF_DATE 20u
#define OFF_SERIAL 24u
#define OFF_CONSISTENCY 40u
#define OFF_CRC 60u

/* Finite test without libm: NaN fails f == f, infinities fail the range. */
static int is_finite(float f)
{
    return f == f && f <= 3.4028235e38f && f >= -3.4028235e38f;
}

static int record_values_ok(const hd_calib_record_t *r)
{
    return is_finite(r->gain_nm_per_v) && r->gain_nm_per_v > 0.0f &&
           is_finite(r->offset_v) && is_finite(r->consistency) &&
           r->consistency >= 0.0f;
}

void hd_calib_record_default(hd_calib_record_t *r)
{
    if (r == NULL) {
        return;
    }
    memset(r, 0, sizeof *r);
    r->gain_nm_per_v = HD_CALIB_NOMINAL_GAIN_NM_PER_V;
    r->offset_v = 0.0f;
}

size_t hd_calib_record_encode(const hd_calib_record_t *r, uint32_t sequence,
                              uint8_t *buf, size_t cap)
{
    if (r == NULL || buf == NULL || cap < HD_CALIB_RECORD_BYTES || !record_values_ok(r)) {
        return 0u;
    }
    memset(buf, 0, HD_CALIB_RECORD_BYTES);
    hd_le_put_u32(buf + OFF_MAGIC, HD_CALIB_RECORD_MAGIC);
    hd_le_put_u16(buf + OFF_VERSION, (uint16_t)HD_CALIB_RECORD_VERSION);
    hd_le_put_u16(buf + OFF_LENGTH, (uint16_t)HD_CALIB_RECORD_BYTES);
    hd_le_put_u32(buf + OFF_SEQUENCE, sequence);
    hd_le_put_f32(buf + OFF_GAIN, r->gain_nm_per_v);
    hd_le_put_f32(buf + OFF_OFFSET, r->offset_v);
    hd_le_put_u32(buf + OFF_DATE, r->calibrated_unix_s);
    memcpy(buf + OFF_SERIAL, r->serial, sizeof r->serial);
    hd_le_put_f32(buf + OFF_CONSISTENCY, r->consistency);
    hd_le_put_u32(buf + OFF_CRC, hd_crc32(buf, OFF_CRC));
    return HD_CALIB_RECORD_BYTES;
}

static int all_erased(const uint8_t *buf, size_t len)
{
    for (size_t i = 0; i < len; ++i) {
        if (buf[i] != 0xFFu) {
            return 0;
        }
    }
    return 1;
}

hd_record_status_t hd_calib_record_decode(const uint8_t *buf, size_t len, hd_calib_record_t *r,
                                          uint32_t *sequence)
{
    if (buf == NULL || r == NULL || len < HD_CALIB_RECORD_BYTES) {
        return HD_RECORD_IO;
    }
    if (all_erased(buf, HD_CALIB_RECORD_BYTES)) {
        return HD_RECORD_MISSING;
    }
    if (hd_le_get_u32(buf + OFF_MAGIC) != HD_CALIB_RECORD_MAGIC ||
        hd_le_get_u32(buf + OFF_CRC) != hd_crc32(buf, OFF_CRC)) {
        return HD_RECORD_CORRUPT;
    }
    /* Intact bytes: only now is the version field trustworthy. */
    if (hd_le_get_u16(buf + OFF_VERSION) != HD_CALIB_RECORD_VERSION) {
        return HD_RECORD_BAD_VERSION;
    }
    if (hd_le_get_u16(buf + OFF_LENGTH) != HD_CALIB_RECORD_BYTES) {
        return HD_RECORD_CORRUPT;
    }
    hd_calib_record_t tmp;
    memset(&tmp, 0, sizeof tmp);
    tmp.gain_nm_per_v = hd_le_get_f32(buf + OFF_GAIN);
    tmp.offset_v = hd_le_get_f32(buf + OFF_OFFSET);
    tmp.calibrated_unix_s = hd_le_get_u32(buf + OFF_DATE);
    memcpy(tmp.serial, buf + OFF_SERIAL, sizeof tmp.serial);
    tmp.consistency = hd_le_get_f32(buf + OFF_CONSISTENCY);
    /* A CRC-valid record with impossible values was written by a bug, not by
     * a calibration: refuse it rather than use it. */
    if (!record_values_ok(&tmp)) {
        return HD_RECORD_CORRUPT;
    }
    *r = tmp;
    if (sequence != NULL) {
        *sequence = hd_le_get_u32(buf + OFF_SEQUENCE);
    }
    return HD_RECORD_OK;
}

hd_record_status_t hd_calib_store_load(const hd_calib_storage_t *s, hd_calib_record_t *r,
                                       uint32_t *sequence)
{
    if (r == NULL) {
        return HD_RECORD_IO;
    }
    hd_calib_record_default(r);
    if (sequence != NULL) {
        *sequence = 0u;
    }
    uint8_t buf[HD_CALIB_RECORD_BYTES];
    size_t len = 0u;
    uint32_t seq = 0u;
    hd_record_status_t st = hd_store_load(s, HD_RECORD_KIND_CALIB, HD_CALIB_RECORD_VERSION, buf,
                                          sizeof buf, &len, &seq, NULL);
    if (st != HD_RECORD_OK && st != HD_RECORD_ONE_COPY_BAD) {
        return st;
    }
    hd_calib_record_t tmp;
    hd_record_status_t dec = (len == HD_CALIB_RECORD_BYTES)
                                 ? hd_calib_record_decode(buf, len, &tmp, NULL)
                                 : HD_RECORD_CORRUPT;
    if (dec != HD_RECORD_OK) {
        /* Intact in the store but not a usable record (written by a bug). */
        return dec == HD_RECORD_BAD_VERSION ? HD_RECORD_BAD_VERSION : HD_RECORD_CORRUPT;
    }
    *r = tmp;
    if (sequence != NULL) {
        *sequence = seq;
    }
    return st;
}

hd_record_status_t hd_calib_store_save(const hd_calib_storage_t *s, const hd_calib_record_t *r)
{
    uint8_t buf[HD_CALIB_RECORD_BYTES];
    /* The store numbers its copies; the record's own sequence field stays 0. */
    if (hd_calib_record_encode(r, 0u, buf, sizeof buf) != HD_CALIB_RECORD_BYTES) {
        return HD_RECORD_CORRUPT;
    }
    return hd_store_save(s, HD_RECORD_KIND_CALIB, HD_CALIB_RECORD_VERSION, buf, sizeof buf);
}
