/*
 * hd_calib_record: the calibration record the firmware uses, and its
 * power-loss-safe storage in two alternating copies.
 *
 * Pure library: no HAL, no I/O, no heap, no globals.  Storage is reached
 * through hd_calib_storage_t, which has the same shape as hal_nvm_t so the
 * firmware can pass its NVM part straight through.
 *
 * Encoded layout of one copy (HD_CALIB_RECORD_BYTES = 64, little-endian):
 *   0  u32  magic 0x52434448 ("HDCR")  -- written LAST, so a copy is only
 *                                         ever valid once every byte is in
 *   4  u16  format version (HD_CALIB_RECORD_VERSION)
 *   6  u16  encoded length (64)
 *   8  u32  sequence number (newer copy = larger, serial-number arithmetic)
 *  12  f32  gain_nm_per_v
 *  16  f32  offset_v
 *  20  u32  calibrated_unix_s
 *  24  16B  serial (NUL-padded)
 *  40  f32  consistency
 *  44  16B  reserved (zero)
 *  60  u32  CRC-32 (IEEE, as zlib) of bytes 0..59
 * See docs/calibration.md.
 */
#ifndef HD_CALIB_RECORD_H
#define HD_CALIB_RECORD_H

#include <stddef.h>
#include <stdint.h>

#ifdef __cplusplus
extern "C" {
#endif

#define HD_CALIB_RECORD_VERSION 1u
#define HD_CALIB_RECORD_MAGIC 0x52434448u /* "HDCR" little-endian */
#define HD_CALIB_NOMINAL_GAIN_NM_PER_V 6.60f /* Taghirad 1997, Table I */

typedef struct {
    float gain_nm_per_v;        /* torque = gain_nm_per_v * (bridge_v - offset_v) */
    float offset_v;
    uint32_t calibrated_unix_s; /* date of calibration */
    char serial[16];            /* sensor serial, NUL-padded */
    float consistency;          /* std/mean of per-experiment gains (fraction), informational */
} hd_calib_record_t;

/* Storage callbacks: same shape as hal_nvm_t in hal/hal.h, but calib/ must
 * not include hal.h (pure library).  Needs size >= 2 * HD_CALIB_RECORD_BYTES;
 * copy A lives at offset 0, copy B at offset size/2 (so each copy can sit in
 * its own flash sector).  Callbacks return 0 on success, negative on error. */
typedef struct {
    void *ctx; size_t size;
    int (*read)(void *ctx, size_t offset, void *buf, size_t len);
    int (*write)(void *ctx, size_t offset, const void *buf, size_t len);
    int (*erase)(void *ctx, size_t offset, size_t len);
} hd_calib_storage_t;

typedef enum {
    HD_CALIB_LOAD_OK = 0,           /* newest valid copy returned */
    HD_CALIB_LOAD_ONE_COPY_BAD = 1, /* valid copy returned, the other copy is damaged (warning) */
    HD_CALIB_LOAD_MISSING = -1,     /* both copies blank: defaults returned */
    HD_CALIB_LOAD_CORRUPT = -2,     /* no copy passes CRC/sanity: defaults returned */
    HD_CALIB_LOAD_BAD_VERSION = -3, /* intact copy of an unknown format version: defaults returned */
    HD_CALIB_LOAD_IO = -4           /* storage error / bad arguments: defaults returned */
} hd_calib_load_t;

#define HD_CALIB_RECORD_BYTES 64u   /* encoded size of one copy (fixed) */

/* Safe defaults (nominal gain 6.60 Nm/V, offset 0, date 0, serial "", consistency 0). */
void hd_calib_record_default(hd_calib_record_t *r);
/* Encodes r with `sequence` into buf (cap >= 64).  Returns 64, or 0 on bad
 * arguments (NULL, cap too small, non-finite or non-positive gain,
 * non-finite offset/consistency). */
size_t hd_calib_record_encode(const hd_calib_record_t *r, uint32_t sequence, uint8_t *buf, size_t cap);
/* Decodes one copy.  Returns 0, or HD_CALIB_LOAD_MISSING (all 0xFF),
 * HD_CALIB_LOAD_CORRUPT (magic/length/CRC/values), HD_CALIB_LOAD_BAD_VERSION
 * (intact but other version), HD_CALIB_LOAD_IO (bad arguments).  r and
 * sequence are written only on success (sequence may be NULL). */
int hd_calib_record_decode(const uint8_t *buf, size_t len, hd_calib_record_t *r, uint32_t *sequence);
/* Newest valid of two copies; on MISSING/CORRUPT/BAD_VERSION/IO fills r with
 * defaults (and *sequence = 0).  The caller must raise a fault flag on any
 * negative return: the defaults are never a calibration. */
hd_calib_load_t hd_calib_store_load(const hd_calib_storage_t *s, hd_calib_record_t *r, uint32_t *sequence);
/* Writes the older (or damaged) slot with sequence+1: erase, write bytes
 * 4..63, then the magic, then read back and verify.  A power loss at any
 * byte leaves the previous valid copy readable.  Returns 0 or a negative
 * hd_calib_load_t (HD_CALIB_LOAD_IO on storage errors / verify failure,
 * HD_CALIB_LOAD_CORRUPT if r cannot be encoded). */
int hd_calib_store_save(const hd_calib_storage_t *s, const hd_calib_record_t *r);
/* CRC-32 (IEEE 802.3, reflected, as zlib), bitwise, table-free. */
uint32_t hd_crc32(const void *data, size_t len);
/* Incremental form: crc = hd_crc32_update(0, a, n); crc = hd_crc32_update(crc, b, m). */
uint32_t hd_crc32_update(uint32_t crc, const void *data, size_t len);

#ifdef __cplusplus
}
#endif

#endif /* HD_CALIB_RECORD_H */
