/*
 * hd_calib_record: the calibration record the firmware uses, and its
 * power-loss-safe storage in two alternating copies.
 *
 * Pure library: no HAL, no I/O, no heap, no globals.  The record is kept
 * in the firmware's record store (hd_record_store.h, kind
 * HD_RECORD_KIND_CALIB) next to the configuration and profile records; the
 * same 64 bytes are the file `hdsense calib --record` writes.
 *
 * Encoded layout (HD_CALIB_RECORD_BYTES = 64, little-endian):
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
 * See docs/how-to/calibration.md.
 */
#ifndef HD_CALIB_RECORD_H
#define HD_CALIB_RECORD_H

#include <stddef.h>
#include <stdint.h>

#include "hd_record_store.h"

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

/* The store the record lives in (hd_record_store.h). */
typedef hd_store_io_t hd_calib_storage_t;

#define HD_CALIB_RECORD_BYTES 64u   /* encoded size of one copy (fixed) */

/* Safe defaults (nominal gain 6.60 Nm/V, offset 0, date 0, serial "", consistency 0). */
void hd_calib_record_default(hd_calib_record_t *r);
/* Encodes r with `sequence` into buf (cap >= 64).  Returns 64, or 0 on bad
 * arguments (NULL, cap too small, non-finite or non-positive gain,
 * non-finite offset/consistency). */
size_t hd_calib_record_encode(const hd_calib_record_t *r, uint32_t sequence, uint8_t *buf, size_t cap);
/* Decodes one record.  Returns HD_RECORD_OK, or HD_RECORD_MISSING (all
 * 0xFF), HD_RECORD_CORRUPT (magic/length/CRC/values), HD_RECORD_BAD_VERSION
 * (intact but other version), HD_RECORD_IO (bad arguments).  r and sequence
 * are written only on success (sequence may be NULL). */
hd_record_status_t hd_calib_record_decode(const uint8_t *buf, size_t len, hd_calib_record_t *r,
                                          uint32_t *sequence);
/* Loads the record from the store.  On anything but OK / ONE_COPY_BAD, r
 * holds the defaults (and *sequence = 0): the caller must raise a fault
 * flag, the defaults are never a calibration. */
hd_record_status_t hd_calib_store_load(const hd_calib_storage_t *s, hd_calib_record_t *r,
                                       uint32_t *sequence);
/* Saves the record into the store (power-loss safe, see
 * hd_record_store.h).  Returns HD_RECORD_OK, HD_RECORD_CORRUPT if r cannot
 * be encoded, or HD_RECORD_IO. */
hd_record_status_t hd_calib_store_save(const hd_calib_storage_t *s, const hd_calib_record_t *r);

#ifdef __cplusplus
}
#endif

#endif /* HD_CALIB_RECORD_H */
