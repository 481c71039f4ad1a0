/* Calibration record: encoding, CRC-32 and two-copy power-loss-safe storage. */
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

uint32_t hd_crc32_update(uint32_t crc, const void *data, size_t len)
{
    const uint8_t *p = (const uint8_t *)data;
    crc = ~crc;
    for (size_t i = 0; i < len; ++i) {
        crc ^= p[i];
        for (unsigned b = 0; b < 8u; ++b) {
            /* Reflected polynomial 0xEDB88320 (IEEE 802.3). */
            crc = (crc >> 1) ^ (0xEDB88320u & (0u - (crc & 1u)));
        }
    }
    return ~crc;
}

uint32_t hd_crc32(const void *data, size_t len)
{
    return hd_crc32_update(0u, data, len);
}

static void put_u16(uint8_t *b, uint16_t v)
{
    b[0] = (uint8_t)(v & 0xFFu);
    b[1] = (uint8_t)(v >> 8);
}

static void put_u32(uint8_t *b, uint32_t v)
{
    for (unsigned i = 0; i < 4u; ++i) {
        b[i] = (uint8_t)(v >> (8u * i));
    }
}

static uint16_t get_u16(const uint8_t *b)
{
    return (uint16_t)(b[0] | (b[1] << 8));
}

static uint32_t get_u32(const uint8_t *b)
{
    return (uint32_t)b[0] | ((uint32_t)b[1] << 8) | ((uint32_t)b[2] << 16) |
           ((uint32_t)b[3] << 24);
}

static void put_f32(uint8_t *b, float f)
{
    uint32_t v;
    memcpy(&v, &f, sizeof v);
    put_u32(b, v);
}

static float get_f32(const uint8_t *b)
{
    uint32_t v = get_u32(b);
    float f;
    memcpy(&f, &v, sizeof f);
    return f;
}

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
    put_u32(buf + OFF_MAGIC, HD_CALIB_RECORD_MAGIC);
    put_u16(buf + OFF_VERSION, (uint16_t)HD_CALIB_RECORD_VERSION);
    put_u16(buf + OFF_LENGTH, (uint16_t)HD_CALIB_RECORD_BYTES);
    put_u32(buf + OFF_SEQUENCE, sequence);
    put_f32(buf + OFF_GAIN, r->gain_nm_per_v);
    put_f32(buf + OFF_OFFSET, r->offset_v);
    put_u32(buf + OFF_DATE, r->calibrated_unix_s);
    memcpy(buf + OFF_SERIAL, r->serial, sizeof r->serial);
    put_f32(buf + OFF_CONSISTENCY, r->consistency);
    put_u32(buf + OFF_CRC, hd_crc32(buf, OFF_CRC));
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

int hd_calib_record_decode(const uint8_t *buf, size_t len, hd_calib_record_t *r,
                           uint32_t *sequence)
{
    if (buf == NULL || r == NULL || len < HD_CALIB_RECORD_BYTES) {
        return HD_CALIB_LOAD_IO;
    }
    if (all_erased(buf, HD_CALIB_RECORD_BYTES)) {
        return HD_CALIB_LOAD_MISSING;
    }
    if (get_u32(buf + OFF_MAGIC) != HD_CALIB_RECORD_MAGIC ||
        get_u32(buf + OFF_CRC) != hd_crc32(buf, OFF_CRC)) {
        return HD_CALIB_LOAD_CORRUPT;
    }
    /* Intact bytes: only now is the version field trustworthy. */
    if (get_u16(buf + OFF_VERSION) != HD_CALIB_RECORD_VERSION) {
        return HD_CALIB_LOAD_BAD_VERSION;
    }
    if (get_u16(buf + OFF_LENGTH) != HD_CALIB_RECORD_BYTES) {
        return HD_CALIB_LOAD_CORRUPT;
    }
    hd_calib_record_t tmp;
    memset(&tmp, 0, sizeof tmp);
    tmp.gain_nm_per_v = get_f32(buf + OFF_GAIN);
    tmp.offset_v = get_f32(buf + OFF_OFFSET);
    tmp.calibrated_unix_s = get_u32(buf + OFF_DATE);
    memcpy(tmp.serial, buf + OFF_SERIAL, sizeof tmp.serial);
    tmp.consistency = get_f32(buf + OFF_CONSISTENCY);
    /* A CRC-valid record with impossible values was written by a bug, not by
     * a calibration: refuse it rather than use it. */
    if (!record_values_ok(&tmp)) {
        return HD_CALIB_LOAD_CORRUPT;
    }
    *r = tmp;
    if (sequence != NULL) {
        *sequence = get_u32(buf + OFF_SEQUENCE);
    }
    return 0;
}

typedef struct {
    int status;       /* decode result, or HD_CALIB_LOAD_IO on read error */
    uint32_t sequence;
    hd_calib_record_t rec;
} slot_t;

static int storage_ok(const hd_calib_storage_t *s)
{
    return s != NULL && s->read != NULL && s->size >= 2u * HD_CALIB_RECORD_BYTES;
}

static size_t slot_offset(const hd_calib_storage_t *s, unsigned i)
{
    return i == 0u ? 0u : s->size / 2u;
}

static void read_slot(const hd_calib_storage_t *s, unsigned i, slot_t *out)
{
    uint8_t buf[HD_CALIB_RECORD_BYTES];
    out->sequence = 0u;
    if (s->read(s->ctx, slot_offset(s, i), buf, sizeof buf) != 0) {
        out->status = HD_CALIB_LOAD_IO;
        return;
    }
    out->status = hd_calib_record_decode(buf, sizeof buf, &out->rec, &out->sequence);
}

/* Serial-number arithmetic: survives the 2^32 wrap of the sequence. */
static int newer(uint32_t a, uint32_t b)
{
    return (int32_t)(a - b) > 0;
}

/* Index of the newest valid slot, or -1. */
static int newest(const slot_t sl[2])
{
    if (sl[0].status == 0 && sl[1].status == 0) {
        return newer(sl[1].sequence, sl[0].sequence) ? 1 : 0;
    }
    if (sl[0].status == 0) {
        return 0;
    }
    return sl[1].status == 0 ? 1 : -1;
}

hd_calib_load_t hd_calib_store_load(const hd_calib_storage_t *s, hd_calib_record_t *r,
                                    uint32_t *sequence)
{
    if (r == NULL) {
        return HD_CALIB_LOAD_IO;
    }
    hd_calib_record_default(r);
    if (sequence != NULL) {
        *sequence = 0u;
    }
    if (!storage_ok(s)) {
        return HD_CALIB_LOAD_IO;
    }
    slot_t sl[2];
    read_slot(s, 0u, &sl[0]);
    read_slot(s, 1u, &sl[1]);
    int best = newest(sl);
    if (best >= 0) {
        *r = sl[best].rec;
        if (sequence != NULL) {
            *sequence = sl[best].sequence;
        }
        int other = sl[1 - best].status;
        /* A blank other slot is normal after the very first save. */
        return (other == 0 || other == HD_CALIB_LOAD_MISSING) ? HD_CALIB_LOAD_OK
                                                              : HD_CALIB_LOAD_ONE_COPY_BAD;
    }
    /* No usable copy: report the most informative reason. */
    for (unsigned i = 0; i < 2u; ++i) {
        if (sl[i].status == HD_CALIB_LOAD_IO) {
            return HD_CALIB_LOAD_IO;
        }
    }
    for (unsigned i = 0; i < 2u; ++i) {
        if (sl[i].status == HD_CALIB_LOAD_BAD_VERSION) {
            return HD_CALIB_LOAD_BAD_VERSION;
        }
    }
    for (unsigned i = 0; i < 2u; ++i) {
        if (sl[i].status == HD_CALIB_LOAD_CORRUPT) {
            return HD_CALIB_LOAD_CORRUPT;
        }
    }
    return HD_CALIB_LOAD_MISSING;
}

int hd_calib_store_save(const hd_calib_storage_t *s, const hd_calib_record_t *r)
{
    if (!storage_ok(s) || s->write == NULL || s->erase == NULL || r == NULL) {
        return HD_CALIB_LOAD_IO;
    }
    slot_t sl[2];
    read_slot(s, 0u, &sl[0]);
    read_slot(s, 1u, &sl[1]);
    int best = newest(sl);
    /* Never touch the newest valid copy: write the other slot. */
    unsigned target = (best == 0) ? 1u : 0u;
    uint32_t seq = (best >= 0) ? sl[best].sequence + 1u : 1u;

    uint8_t buf[HD_CALIB_RECORD_BYTES];
    if (hd_calib_record_encode(r, seq, buf, sizeof buf) != HD_CALIB_RECORD_BYTES) {
        return HD_CALIB_LOAD_CORRUPT;
    }
    size_t base = slot_offset(s, target);
    /* Erase, then everything but the magic, then the magic: until the last
     * magic byte lands the copy fails the magic check deterministically
     * (the magic has no 0xFF byte), whatever the CRC happens to be. */
    if (s->erase(s->ctx, base, s->size / 2u) != 0 ||
        s->write(s->ctx, base + 4u, buf + 4u, HD_CALIB_RECORD_BYTES - 4u) != 0 ||
        s->write(s->ctx, base, buf, 4u) != 0) {
        return HD_CALIB_LOAD_IO;
    }
    uint8_t check[HD_CALIB_RECORD_BYTES];
    if (s->read(s->ctx, base, check, sizeof check) != 0 ||
        memcmp(check, buf, sizeof buf) != 0) {
        return HD_CALIB_LOAD_IO;
    }
    return 0;
}
