/*
 * hd_fw_records: the configuration record's payload (the calibration
 * record's is hd_calib_record.h; both live in the record store,
 * hd_record_store.h).
 *
 * Payload, little-endian (HD_CONFIG_RECORD_VERSION):
 *   u8  n;  n x { u8 parameter id, f32 value }   every CONFIG row of hd_params.def
 *   u8  b;  b x { u8 lock, u8 enabled, f32 order, f32 q_nm2 }   the filter blocks
 * Parameters are stored by id, so a firmware that gains a parameter still
 * reads an older record (the new one keeps its default).  An id this
 * firmware does not know means a newer firmware wrote the record: it is
 * refused as BAD_VERSION rather than half applied.
 *
 * Pure: no I/O, no heap, no globals.
 */
#ifndef HD_FW_RECORDS_H
#define HD_FW_RECORDS_H

#include <stddef.h>
#include <stdint.h>

#include "hd_fw_config.h"
#include "hd_record_store.h"

#ifdef __cplusplus
extern "C" {
#endif

#define HD_CONFIG_RECORD_VERSION 1u
#define HD_CONFIG_RECORD_MAX 512u

/* Encodes cfg; returns the length, or 0 if cap is too small. */
size_t hd_config_record_encode(const hd_fw_config_t *cfg, uint8_t *buf, size_t cap);
/* Decodes a payload on top of *base into *out (which may be base).
 * Returns HD_RECORD_OK, HD_RECORD_BAD_VERSION (unknown parameter id), or
 * HD_RECORD_CORRUPT (truncated, trailing bytes, a value out of range, a
 * model hd_fw_config_check refuses); *out is written only on OK. */
hd_record_status_t hd_config_record_decode(const uint8_t *buf, size_t len,
                                           const hd_fw_config_t *base, hd_fw_config_t *out);

#ifdef __cplusplus
}
#endif

#endif /* HD_FW_RECORDS_H */
