/* Fuzz: the calibration record loader: hd_calib_record_decode on one copy,
 * hd_calib_store_load on a whole NVM image, and what the firmware makes of
 * that image at boot.  Bit 0 of the first byte asks the harness to fix up
 * the CRC of both copies, so the fuzzer also reaches the value checks
 * behind it.
 * Properties: nothing crashes; a decoded record has a finite gain > 0 and
 * finite offset/consistency and survives encode -> decode unchanged;
 * store_load returns a documented code, defaults on failure; the firmware
 * boots on any image, flags exactly the failure store_load reports and
 * uses the 6.60 N m/V default whenever no copy is valid. */
#include <math.h>
#include <string.h>

#include "fuzz.h"
#include "hal_mock.h"
#include "hd_calib_record.h"
#include "hd_fw.h"

static hal_mock_t mock;
static hd_fw_t fw;

static void fix_crc(uint8_t *copy)
{
    uint32_t c = hd_crc32(copy, 60);
    copy[60] = (uint8_t)c;
    copy[61] = (uint8_t)(c >> 8);
    copy[62] = (uint8_t)(c >> 16);
    copy[63] = (uint8_t)(c >> 24);
}

static void check_record(const hd_calib_record_t *r, uint32_t seq)
{
    FUZZ_CHECK(isfinite(r->gain_nm_per_v) && r->gain_nm_per_v > 0.0f);
    FUZZ_CHECK(isfinite(r->offset_v) && isfinite(r->consistency));
    uint8_t buf[HD_CALIB_RECORD_BYTES];
    FUZZ_CHECK(hd_calib_record_encode(r, seq, buf, sizeof buf) == HD_CALIB_RECORD_BYTES);
    hd_calib_record_t back;
    uint32_t seq2 = 0;
    FUZZ_CHECK(hd_calib_record_decode(buf, sizeof buf, &back, &seq2) == 0);
    FUZZ_CHECK(seq2 == seq && memcmp(&back, r, sizeof back) == 0);
}

int LLVMFuzzerTestOneInput(const uint8_t *data, size_t size)
{
    hal_mock_init(&mock);
    size_t n = size < HAL_MOCK_NVM_BYTES ? size : HAL_MOCK_NVM_BYTES;
    memcpy(mock.nvm, data, n);
    if (size > 0u && (data[0] & 1u)) {
        fix_crc(&mock.nvm[0]);
        fix_crc(&mock.nvm[HAL_MOCK_NVM_BYTES / 2u]);
    }
    /* one copy, any length */
    hd_calib_record_t r;
    memset(&r, 0, sizeof r);
    uint32_t seq = 0;
    int rc = hd_calib_record_decode(data, size, &r, &seq);
    FUZZ_CHECK(rc == 0 || rc == HD_CALIB_LOAD_MISSING || rc == HD_CALIB_LOAD_CORRUPT ||
               rc == HD_CALIB_LOAD_BAD_VERSION || rc == HD_CALIB_LOAD_IO);
    if (rc == 0) {
        check_record(&r, seq);
    }
    rc = hd_calib_record_decode(mock.nvm, HD_CALIB_RECORD_BYTES, &r, &seq);
    if (rc == 0) {
        check_record(&r, seq);
    }
    /* the whole image */
    hal_t hal;
    hal_mock_bind(&mock, &hal);
    hd_calib_storage_t st = {hal.nvm.ctx, hal.nvm.size, hal.nvm.read, hal.nvm.write, hal.nvm.erase};
    int lrc = hd_calib_store_load(&st, &r, &seq);
    FUZZ_CHECK(lrc >= HD_CALIB_LOAD_IO && lrc <= HD_CALIB_LOAD_ONE_COPY_BAD);
    if (lrc >= 0) {
        check_record(&r, seq);
    } else {
        FUZZ_CHECK(r.gain_nm_per_v == HD_CALIB_NOMINAL_GAIN_NM_PER_V && seq == 0u);
    }
    /* the firmware at boot */
    hd_fw_config_t cfg;
    hd_fw_config_default(&cfg);
    FUZZ_CHECK(hd_fw_init(&fw, &hal, &cfg) == HD_FW_OK);
    /* The firmware reports the loader's verdict, except that an intact
     * record with an implausible gain or offset counts as corrupt. */
    int expect = lrc;
    if (lrc >= 0 && (!(r.gain_nm_per_v <= HD_FW_CALIB_GAIN_MAX_NM_PER_V) ||
                     !(fabsf(r.offset_v) <= HD_FW_CALIB_OFFSET_MAX_V))) {
        expect = HD_CALIB_LOAD_CORRUPT;
    }
    FUZZ_CHECK(fw.calib_load_result == expect);
    uint16_t want = expect == HD_CALIB_LOAD_OK            ? 0u
                    : expect == HD_CALIB_LOAD_ONE_COPY_BAD ? HD_FAULT_CALIB_ONE_COPY
                    : expect == HD_CALIB_LOAD_MISSING      ? HD_FAULT_CALIB_MISSING
                                                           : HD_FAULT_CALIB_CORRUPT;
    FUZZ_CHECK(fw.calib_faults == want);
    if (expect < 0) {
        FUZZ_CHECK(fw.calib.gain_nm_per_v == HD_CALIB_NOMINAL_GAIN_NM_PER_V);
    } else {
        FUZZ_CHECK(fw.calib.gain_nm_per_v == r.gain_nm_per_v);
    }
    return 0;
}
