/* Fuzz: the record store as the firmware meets it at boot: a whole NVM
 * image (both halves, any bytes) -> hd_store_load of every kind, the
 * calibration and configuration decoders, and hd_fw_init.  Bit 0 of the
 * first byte asks the harness to fix up the header and payload CRCs of both
 * halves, so the fuzzer also reaches the checks behind them.
 * Properties: nothing crashes; every load returns a documented status; a
 * decoded calibration record has a finite gain > 0 and survives encode ->
 * decode; a decoded configuration passes hd_fw_config_check; the firmware
 * boots on any image, reports exactly the calibration status the loader
 * gives (an intact but implausible record counting as corrupt) and uses
 * the 6.60 N m/V default whenever no record is usable. */
#include <math.h>
#include <string.h>

#include "fuzz.h"
#include "hal_mock.h"
#include "hd_calib_record.h"
#include "hd_fw.h"
#include "hd_fw_records.h"

static hal_mock_t mock;
static hd_fw_t fw;

/* Recomputes the CRCs of one half so its header and payloads are intact. */
static void fix_crcs(uint8_t *c, size_t half)
{
    unsigned n = c[12];
    if (n > HD_STORE_MAX_RECORDS) {
        return;
    }
    size_t dir_end = HD_STORE_HEADER_BYTES + HD_STORE_ENTRY_BYTES * n;
    for (unsigned i = 0; i < n; i++) {
        uint8_t *e = c + HD_STORE_HEADER_BYTES + HD_STORE_ENTRY_BYTES * i;
        size_t off = hd_le_get_u16(e + 4), len = hd_le_get_u16(e + 6);
        if (off + len <= half) {
            hd_le_put_u32(e + 8, hd_crc32(c + off, len));
        }
    }
    hd_le_put_u32(c + dir_end, hd_crc32(c + 4, dir_end - 4));
}

static void check_calib(const hd_calib_record_t *r)
{
    FUZZ_CHECK(isfinite(r->gain_nm_per_v) && r->gain_nm_per_v > 0.0f);
    FUZZ_CHECK(isfinite(r->offset_v) && isfinite(r->consistency));
    uint8_t buf[HD_CALIB_RECORD_BYTES];
    FUZZ_CHECK(hd_calib_record_encode(r, 0u, buf, sizeof buf) == HD_CALIB_RECORD_BYTES);
    hd_calib_record_t back;
    FUZZ_CHECK(hd_calib_record_decode(buf, sizeof buf, &back, NULL) == HD_RECORD_OK);
    FUZZ_CHECK(memcmp(&back, r, sizeof back) == 0);
}

static bool usable(int st)
{
    return st == HD_RECORD_OK || st == HD_RECORD_ONE_COPY_BAD;
}

int LLVMFuzzerTestOneInput(const uint8_t *data, size_t size)
{
    hal_mock_init(&mock);
    size_t n = size < HAL_MOCK_NVM_BYTES ? size : HAL_MOCK_NVM_BYTES;
    memcpy(mock.nvm, data, n);
    if (size > 0u && (data[0] & 1u)) {
        fix_crcs(&mock.nvm[0], HAL_MOCK_NVM_BYTES / 2u);
        fix_crcs(&mock.nvm[HAL_MOCK_NVM_BYTES / 2u], HAL_MOCK_NVM_BYTES / 2u);
    }
    hal_t hal;
    hal_mock_bind(&mock, &hal);
    hd_store_io_t io = hd_fw_store_io(&hal, NULL, 0u);
    /* every kind, raw */
    for (unsigned kind = 0; kind < 5u; kind++) {
        uint8_t buf[HD_STORE_IMAGE_MAX];
        size_t len = 0;
        int st = hd_store_load(&io, (uint8_t)kind, 1u, buf, sizeof buf, &len, NULL, NULL);
        FUZZ_CHECK(st >= HD_RECORD_OK && st <= HD_RECORD_IO);
        FUZZ_CHECK(!usable(st) || len <= sizeof buf);
        if (kind == HD_RECORD_KIND_CONFIG && usable(st)) {
            hd_fw_config_t base, out;
            hd_fw_config_default(&base);
            if (hd_config_record_decode(buf, len, &base, &out) == HD_RECORD_OK) {
                FUZZ_CHECK(hd_fw_config_check(&out, NULL) == HD_FW_OK);
            }
        }
    }
    /* the calibration through its own loader */
    hd_calib_record_t r;
    uint32_t seq = 0;
    int lrc = hd_calib_store_load(&io, &r, &seq);
    if (usable(lrc)) {
        check_calib(&r);
    } else {
        FUZZ_CHECK(r.gain_nm_per_v == HD_CALIB_NOMINAL_GAIN_NM_PER_V && seq == 0u);
    }
    /* the firmware at boot */
    hd_fw_config_t cfg;
    hd_fw_config_default(&cfg);
    FUZZ_CHECK(hd_fw_init(&fw, &hal, &cfg) == HD_FW_OK);
    int expect = lrc;
    if (usable(lrc) && (!(r.gain_nm_per_v <= HD_FW_CALIB_GAIN_MAX_NM_PER_V) ||
                        !(fabsf(r.offset_v) <= HD_FW_CALIB_OFFSET_MAX_V))) {
        expect = HD_RECORD_CORRUPT;
    }
    FUZZ_CHECK(hd_fw_record_status(&fw, HD_RECORD_KIND_CALIB) == expect);
    uint32_t want = expect == HD_RECORD_OK            ? 0u
                    : expect == HD_RECORD_ONE_COPY_BAD ? HD_FAULT_CALIB_ONE_COPY
                    : expect == HD_RECORD_MISSING      ? HD_FAULT_CALIB_MISSING
                                                       : HD_FAULT_CALIB_CORRUPT;
    const hd_fw_settings_t *s = &fw.settings[fw.live_settings];
    FUZZ_CHECK((s->record_faults & (HD_FAULT_CALIB_ONE_COPY | HD_FAULT_CALIB_MISSING |
                                    HD_FAULT_CALIB_CORRUPT)) == want);
    FUZZ_CHECK(hd_fw_config_check(hd_fw_config(&fw), NULL) == HD_FW_OK);
    if (!usable(expect)) {
        FUZZ_CHECK(hd_fw_config(&fw)->calib_gain_nm_per_v == HD_CALIB_NOMINAL_GAIN_NM_PER_V);
    } else {
        FUZZ_CHECK(hd_fw_config(&fw)->calib_gain_nm_per_v == r.gain_nm_per_v);
    }
    return 0;
}
