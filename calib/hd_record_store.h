/*
 * hd_record_store: the firmware's records (calibration, configuration,
 * profile) in one store of two alternating copies, safe against power loss
 * at any byte.
 *
 * Pure library: no HAL, no I/O, no heap, no globals.  Storage is reached
 * through hd_store_io_t, which has the shape of hal_nvm_t (hal/hal.h) plus a
 * work buffer, so the firmware passes its NVM part straight through.
 *
 * Layout.  Copy A occupies [0, size/2), copy B [size/2, size); on flash each
 * half is one erase unit.  One copy, little-endian:
 *   0   u32  magic 0x54534448 ("HDST"), written LAST: a copy is valid only
 *            once every other byte is in
 *   4   u16  store format (HD_STORE_FORMAT)
 *   6   u16  image length (header + directory + payloads)
 *   8   u32  sequence number (the newer copy is larger, serial arithmetic)
 *   12  u8   record count n (<= HD_STORE_MAX_RECORDS), then 3 zero bytes
 *   16  n x  { u8 kind, u8 0, u16 version, u16 offset, u16 length,
 *              u32 CRC-32 of the payload }
 *   16 + 12 n   u32 CRC-32 of bytes 4 .. 16 + 12 n
 *   then the payloads at their offsets.
 *
 * Contract.
 *  - The newest copy with a valid header is authoritative for which records
 *    exist: a record it lacks is MISSING (a cleared record does not come
 *    back from the older copy).
 *  - A record whose payload fails its CRC in the newest copy is read from
 *    the older copy when that one holds it intact (ONE_COPY_BAD).
 *  - hd_store_save writes one record (or removes it) and carries every
 *    other record forward from its newest intact copy, into the older (or
 *    damaged) half: erase that half, write bytes 4.., then the magic, then
 *    read back and compare.  Until the magic is in, the previous copy is
 *    the valid one, so a power loss at any byte loses at most this save.
 *  - Saves need io->work, at least HD_STORE_IMAGE_MAX bytes (the image is
 *    built there so a record living only in the half being erased survives).
 * docs/reference/records.md has the tests behind each point.
 */
#ifndef HD_RECORD_STORE_H
#define HD_RECORD_STORE_H

#include <stddef.h>
#include <stdint.h>

#ifdef __cplusplus
extern "C" {
#endif

#define HD_STORE_MAGIC 0x54534448u /* "HDST" little-endian */
#define HD_STORE_FORMAT 1u
#define HD_STORE_MAX_RECORDS 4u
#define HD_STORE_HEADER_BYTES 16u
#define HD_STORE_ENTRY_BYTES 12u
#define HD_STORE_IMAGE_MAX 1024u  /* largest image; each half must hold it */
#define HD_STORE_MIN_SIZE (2u * HD_STORE_IMAGE_MAX)

/* Record kinds (one byte in the directory). */
typedef enum {
    HD_RECORD_KIND_CALIB = 1,
    HD_RECORD_KIND_CONFIG = 2,
    HD_RECORD_KIND_PROFILE = 3,
} hd_record_kind_t;

/* Outcome of loading a record; the codes are the protocol's record status
 * (firmware/hd_protocol.def HD_RECORD_STATUS), so they travel on CAN as is. */
typedef enum {
    HD_RECORD_OK = 0,            /* newest copy valid */
    HD_RECORD_ONE_COPY_BAD = 1,  /* a valid copy returned, the other one damaged */
    HD_RECORD_MISSING = 2,       /* never saved (or removed) */
    HD_RECORD_CORRUPT = 3,       /* no copy passes its checks */
    HD_RECORD_BAD_VERSION = 4,   /* intact, but of another format version */
    HD_RECORD_IO = 5,            /* storage error or bad arguments */
    HD_RECORD_REFUSED = 6,       /* intact, but the caller cannot use it (set by callers) */
} hd_record_status_t;

/* Same shape as hal_nvm_t, plus the work buffer saves need.  Callbacks
 * return 0 on success, negative on error. */
typedef struct {
    void *ctx;
    size_t size;
    int (*read)(void *ctx, size_t offset, void *buf, size_t len);
    int (*write)(void *ctx, size_t offset, const void *buf, size_t len);
    int (*erase)(void *ctx, size_t offset, size_t len);
    uint8_t *work;               /* >= HD_STORE_IMAGE_MAX bytes, for saves */
    size_t work_size;
} hd_store_io_t;

/* Loads record `kind` into buf (cap bytes).  On OK / ONE_COPY_BAD, *len is
 * the payload length and *sequence (may be NULL) the copy's sequence; on
 * BAD_VERSION *version (may be NULL) is the stored version and nothing is
 * copied.  A payload longer than cap is CORRUPT. */
hd_record_status_t hd_store_load(const hd_store_io_t *io, uint8_t kind, uint16_t version,
                                 uint8_t *buf, size_t cap, size_t *len, uint32_t *sequence,
                                 uint16_t *stored_version);

/* Saves record `kind` (payload of len bytes, version); payload NULL removes
 * it.  Returns HD_RECORD_OK, or HD_RECORD_IO (storage error, verify
 * failure, bad arguments, or the image would not fit a half). */
hd_record_status_t hd_store_save(const hd_store_io_t *io, uint8_t kind, uint16_t version,
                                 const uint8_t *payload, size_t len);

/* CRC-32 (IEEE 802.3, reflected, as zlib), bitwise, table-free. */
uint32_t hd_crc32(const void *data, size_t len);
/* Incremental form: crc = hd_crc32_update(0, a, n); crc = hd_crc32_update(crc, b, m). */
uint32_t hd_crc32_update(uint32_t crc, const void *data, size_t len);

/* Little-endian helpers shared by the record codecs. */
void hd_le_put_u16(uint8_t *p, uint16_t v);
void hd_le_put_u32(uint8_t *p, uint32_t v);
void hd_le_put_f32(uint8_t *p, float v);
uint16_t hd_le_get_u16(const uint8_t *p);
uint32_t hd_le_get_u32(const uint8_t *p);
float hd_le_get_f32(const uint8_t *p);

#ifdef __cplusplus
}
#endif

#endif /* HD_RECORD_STORE_H */
