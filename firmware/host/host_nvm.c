#include "host_nvm.h"

#include <errno.h>
#include <stdio.h>
#include <stdlib.h>
#include <string.h>
#include <sys/stat.h>

#include "hd_fw.h"
#include "hd_fw_records.h"
#include "hd_hostio.h"

int host_provision_calibration(hal_t *hal, float gain, float offset)
{
    hd_calib_record_t rec;
    hd_calib_record_default(&rec);
    rec.gain_nm_per_v = gain;
    rec.offset_v = offset;
    static uint8_t work[HD_STORE_IMAGE_MAX];
    const hd_calib_storage_t s = hd_fw_store_io(hal, work, sizeof work);
    return hd_calib_store_save(&s, &rec) == HD_RECORD_OK ? 0 : -1;
}

/* A profile record file (docs/design/slow-torque.md, "Record file"): "HDPF", u16
 * format version, u16 payload length, the payload of hd_fw_records.h, u32
 * CRC-32 of everything before it.  Stored as is: the firmware checks that
 * it is for this joint at boot (REFUSED otherwise, as on the MCU). */
int host_provision_profile(hal_t *hal, const char *path, char *err, size_t err_len)
{
    size_t len = 0;
    char *buf = hd_hostio_read_file(path, 4096u, &len, err, err_len);
    if (buf == NULL) {
        return -1;
    }
    const uint8_t *b = (const uint8_t *)buf;
    int rc = -1;
    if (len < 12u || memcmp(b, "HDPF", 4) != 0) {
        snprintf(err, err_len, "%s: not a profile record file (no HDPF header)", path);
    } else if (hd_le_get_u16(b + 4) != HD_PROFILE_RECORD_VERSION &&
               hd_le_get_u16(b + 4) != HD_PROFILE_RECORD_VERSION_V1) {
        snprintf(err, err_len, "%s: profile record format %u, this firmware reads %u and %u", path,
                 (unsigned)hd_le_get_u16(b + 4), (unsigned)HD_PROFILE_RECORD_VERSION_V1,
                 (unsigned)HD_PROFILE_RECORD_VERSION);
    } else if ((size_t)hd_le_get_u16(b + 6) + 12u != len ||
               hd_crc32(b, len - 4u) != hd_le_get_u32(b + len - 4u)) {
        snprintf(err, err_len, "%s: profile record file damaged (length or CRC)", path);
    } else {
        static uint8_t work[HD_STORE_IMAGE_MAX];
        const hd_store_io_t s = hd_fw_store_io(hal, work, sizeof work);
        rc = hd_store_save(&s, HD_RECORD_KIND_PROFILE, hd_le_get_u16(b + 4), b + 8,
                           len - 12u) == HD_RECORD_OK ? 0 : -1;
        if (rc != 0) {
            snprintf(err, err_len, "could not store the profile record in NVM");
        }
    }
    free(buf);
    return rc;
}

int host_nvm_load(nvm_file_t *n, uint8_t *nvm, char *err, size_t err_len)
{
    memcpy(n->saved, nvm, sizeof n->saved);
    if (n->path == NULL) {
        return 0;
    }
    struct stat st;
    if (stat(n->path, &st) != 0 && errno == ENOENT) {
        n->missing = true; /* starts erased; written at once (an unwritable path fails now) */
        return 0;
    }
    size_t len = 0;
    char *buf = hd_hostio_read_file(n->path, HAL_MOCK_NVM_BYTES, &len, err, err_len);
    if (buf == NULL) {
        return -1;
    }
    if (len != HAL_MOCK_NVM_BYTES) {
        snprintf(err, err_len, "%s: NVM image of %zu bytes, expected %u (not written by "
                 "hdjoint-host?)", n->path, len, (unsigned)HAL_MOCK_NVM_BYTES);
        free(buf);
        return -1;
    }
    memcpy(nvm, buf, HAL_MOCK_NVM_BYTES);
    memcpy(n->saved, buf, HAL_MOCK_NVM_BYTES);
    free(buf);
    return 0;
}

int host_nvm_sync(nvm_file_t *n, const uint8_t *nvm, char *err, size_t err_len)
{
    if (n->path == NULL || (!n->missing && memcmp(n->saved, nvm, sizeof n->saved) == 0)) {
        return 0;
    }
    if (hd_hostio_write_atomic(n->path, nvm, HAL_MOCK_NVM_BYTES, err, err_len) != 0) {
        return -1;
    }
    memcpy(n->saved, nvm, sizeof n->saved);
    n->missing = false;
    n->writes++;
    return 0;
}
