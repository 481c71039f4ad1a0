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
 * The profile record's payload (HD_PROFILE_RECORD_VERSION), little-endian:
 *   f32 gear_ratio, u32 motor_cpr, u32 output_cpr   the joint it was made on
 *   f32 load_nm    |T| the lines were learned at (hd_kf_profile_t.load_nm;
 *                  negative: unknown)
 *   u8  n;  n x { u8 lock (0 motor, 1 output), u8 order, f32 a_nm, f32 b_nm }
 * Version 1 (HD_PROFILE_RECORD_VERSION_V1) had no load_nm; it is still read,
 * its load unknown.
 * ripple(alpha) = a cos(order alpha) + b sin(order alpha), alpha the absolute
 * motor or output angle (hd_kf.h, "angle-referenced profiles";
 * docs/design/slow-torque.md).  A record for another gear ratio or encoder
 * resolution is REFUSED by the firmware, never scaled.
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

#define HD_PROFILE_RECORD_VERSION 2u
#define HD_PROFILE_RECORD_VERSION_V1 1u
#define HD_PROFILE_RECORD_HEADER 17u
#define HD_PROFILE_RECORD_HEADER_V1 13u
#define HD_PROFILE_RECORD_LINE 10u
#define HD_PROFILE_RECORD_MAX (HD_PROFILE_RECORD_HEADER + HD_PROFILE_RECORD_LINE * HD_KF_MAX_BLOCKS)

typedef struct {
    float gear_ratio;
    uint32_t motor_cpr;
    uint32_t output_cpr;
    hd_kf_profile_t profile;
} hd_profile_record_t;

/* Encodes cfg; returns the length, or 0 if cap is too small. */
size_t hd_config_record_encode(const hd_fw_config_t *cfg, uint8_t *buf, size_t cap);
/* Decodes a payload on top of *base into *out (which may be base).
 * Returns HD_RECORD_OK, HD_RECORD_BAD_VERSION (unknown parameter id), or
 * HD_RECORD_CORRUPT (truncated, trailing bytes, a value out of range, a
 * model hd_fw_config_check refuses); *out is written only on OK. */
hd_record_status_t hd_config_record_decode(const uint8_t *buf, size_t len,
                                           const hd_fw_config_t *base, hd_fw_config_t *out);

/* Encodes r; returns the length, or 0 if cap is too small or r holds more
 * than HD_KF_MAX_BLOCKS lines. */
size_t hd_profile_record_encode(const hd_profile_record_t *r, uint8_t *buf, size_t cap);
/* Decodes a payload of `version` (HD_PROFILE_RECORD_VERSION, or _V1: its
 * load_nm is -1, unknown).  HD_RECORD_OK, HD_RECORD_BAD_VERSION (another
 * version), or HD_RECORD_CORRUPT (length, more lines than
 * HD_KF_MAX_BLOCKS, a lock other than motor/output, order 0, a non-finite
 * number, a gear ratio below 1, a cpr of 0, a load_nm that is not a
 * number or above HD_KF_MAX_ABS_Y_NM); *out is written only on OK. */
hd_record_status_t hd_profile_record_decode(const uint8_t *buf, size_t len, uint16_t version,
                                            hd_profile_record_t *out);

#ifdef __cplusplus
}
#endif

#endif /* HD_FW_RECORDS_H */
