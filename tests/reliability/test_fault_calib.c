/* What the FIRMWARE does with each state of the calibration record (the
 * record store itself is tested in tests/calib): missing, CRC-corrupt, one
 * copy corrupt, wrong version, NVM I/O error, and a power loss at every byte
 * of a CALIB_SAVE issued over CAN.
 *
 * Expectations from docs/design/firmware.md and docs/how-to/calibration.md: the right
 * flag on every tick (telemetry) and the right CalibStatus in the heartbeat;
 * defaults (6.60 N m/V, offset 0) whenever no valid copy exists, the stored
 * values otherwise (the profile record's own states: tests/firmware/
 * test_fw_slow_torque.c; its power-loss sweep is here, with the rig), checked through the torque the firmware computes from
 * known ADC counts; a later good save clears the flag on the next tick.
 * Records with a wrong version are built here with an independent CRC-32. */
#include <math.h>
#include <stdio.h>
#include <string.h>

#include "hal_mock.h"
#include "hd_calib_record.h"
#include "hd_fw.h"
#include "hd_fw_records.h"
#include "rel_measured.h"
#include "unity.h"

static hal_mock_t mock;
static hal_t hal;
static hd_fw_t fw;
static hd_fw_config_t cfg;

#define VPC (10.0 / 32768.0)
#define COUNTS 3000 /* 0.9155 V */
#define NOMINAL_GAIN 6.60
#define STORED_GAIN 6.0f
#define STORED_OFFSET 0.05f
#define NEW_GAIN 7.0f

void setUp(void)
{
    hal_mock_init(&mock);
    hal_mock_bind(&mock, &hal);
    hd_fw_config_default(&cfg);
    cfg.adc_volts_per_count = (float)VPC;
}
void tearDown(void) {}

/* Independent CRC-32 (IEEE 802.3, reflected, init and final xor ~0). */
static uint32_t crc32_ref(const uint8_t *p, size_t n)
{
    uint32_t c = 0xFFFFFFFFu;
    for (size_t i = 0; i < n; i++) {
        c ^= p[i];
        for (int b = 0; b < 8; b++) {
            c = (c >> 1) ^ (0xEDB88320u & (0u - (c & 1u)));
        }
    }
    return ~c;
}

static hd_calib_storage_t storage(const hal_t *h)
{
    static uint8_t work[HD_STORE_IMAGE_MAX];
    return hd_fw_store_io(h, work, sizeof work);
}

/* Where copy `copy`'s calibration payload starts (its directory entry). */
static uint8_t *calib_payload(unsigned copy)
{
    uint8_t *c = &mock.nvm[copy * (HAL_MOCK_NVM_BYTES / 2u)];
    TEST_ASSERT_EQUAL_UINT8(HD_RECORD_KIND_CALIB, c[16]);
    return c + (c[20] | (c[21] << 8));
}

static void store(float gain, float offset)
{
    hd_calib_record_t rec;
    hd_calib_record_default(&rec);
    rec.gain_nm_per_v = gain;
    rec.offset_v = offset;
    hd_calib_storage_t s = storage(&hal);
    TEST_ASSERT_EQUAL_INT(HD_RECORD_OK, hd_calib_store_save(&s, &rec));
}

static void tick(unsigned n)
{
    static uint32_t motor;
    for (unsigned i = 0; i < n; i++) {
        motor += 5u;
        TEST_ASSERT_EQUAL_INT(0, hal_mock_push(&mock, COUNTS, motor));
        hd_fw_isr(&fw);
        hd_fw_background(&fw);
    }
}

static uint8_t last_heartbeat_calib_status(void)
{
    const hal_can_frame_t *hb = NULL;
    for (uint32_t i = 0; i < hal_mock_tx_count(&mock); i++) {
        if (hal_mock_tx(&mock, i)->id == hd_can_id(HD_CAN_FRAME_HEARTBEAT, 1)) {
            hb = hal_mock_tx(&mock, i);
        }
    }
    TEST_ASSERT_NOT_NULL(hb);
    return hb->data[6] & 0x0Fu;
}

/* Init, run a few ticks, check flag, heartbeat status and the torque the
 * firmware computes (which tells the gain and offset in use). */
static void check_boot(const char *name, uint16_t flag, uint8_t status, double gain, double offset_v)
{
    TEST_ASSERT_EQUAL_INT(HD_FW_OK, hd_fw_init(&fw, &hal, &cfg));
    tick(5);
    const hd_fw_sample_t *s = hd_fw_last_sample(&fw);
    TEST_ASSERT_EQUAL_UINT32(flag, s->faults & (HD_FAULT_CALIB_MISSING | HD_FAULT_CALIB_CORRUPT |
                                                HD_FAULT_CALIB_ONE_COPY));
    TEST_ASSERT_EQUAL_UINT8(status, last_heartbeat_calib_status());
    TEST_ASSERT_EQUAL_UINT32(5, fw.counters.by_fault[flag == HD_FAULT_CALIB_MISSING   ? 10
                                                     : flag == HD_FAULT_CALIB_CORRUPT ? 11
                                                                                      : 14]);
    double expect = gain * (COUNTS * VPC - offset_v);
    TEST_ASSERT_DOUBLE_WITHIN(1e-4, expect, (double)s->torque_raw_nm);
    TEST_ASSERT_TRUE(s->valid); /* defaults are usable: the joint keeps running */
    rel_measured(name, "faults=0x%x calib_status=%u gain_nm_per_v=%.3g offset_v=%.3g",
                 (unsigned)(s->faults & (HD_FAULT_CALIB_MISSING | HD_FAULT_CALIB_CORRUPT |
                                         HD_FAULT_CALIB_ONE_COPY)),
                 (unsigned)last_heartbeat_calib_status(),
                 (double)hd_fw_config(&fw)->calib_gain_nm_per_v,
                 (double)hd_fw_config(&fw)->calib_offset_v);
}

/* A CALIB_SAVE over CAN clears the flag on the next tick. */
static void check_recovery_by_save(void)
{
    TEST_ASSERT_EQUAL_UINT8(0, mock.nvm_fail); /* caller made the NVM writable */
    hal_can_frame_t f = {0x01D01001u, 8, HAL_CAN_FLAG_EXT, {0x31, 0x42, 0, 0, 0x10, 0x20, 0x30, 0x40}};
    TEST_ASSERT_EQUAL_INT(0, hal_mock_push_rx(&mock, &f));
    tick(1); /* the command is queued in this tick, written in the background after it */
    tick(1); /* and the cleared flag is live from this one */
    TEST_ASSERT_EQUAL_UINT32(0, hd_fw_last_sample(&fw)->faults &
                                    (HD_FAULT_CALIB_MISSING | HD_FAULT_CALIB_CORRUPT |
                                     HD_FAULT_CALIB_ONE_COPY));
    hd_calib_storage_t s = storage(&hal);
    hd_calib_record_t back;
    uint32_t seq;
    /* the save rewrote the older or damaged slot; if both were damaged the
     * other one stays damaged until the next save (a warning, not a fault) */
    int rc = hd_calib_store_load(&s, &back, &seq);
    TEST_ASSERT_TRUE(rc == HD_RECORD_OK || rc == HD_RECORD_ONE_COPY_BAD);
    TEST_ASSERT_EQUAL_UINT32(0x40302010u, back.calibrated_unix_s);
}

static void test_missing_record(void)
{
    check_boot("calib_missing", HD_FAULT_CALIB_MISSING, 2, NOMINAL_GAIN, 0.0);
    check_recovery_by_save();
}

static void test_crc_corrupt_both_copies(void)
{
    store(STORED_GAIN, STORED_OFFSET);
    store(STORED_GAIN, STORED_OFFSET); /* both copies written */
    calib_payload(0)[14] ^= 0x01u;     /* a gain byte of copy A */
    calib_payload(1)[14] ^= 0x80u;     /* and of copy B */
    check_boot("calib_crc_corrupt", HD_FAULT_CALIB_CORRUPT, 3, NOMINAL_GAIN, 0.0);
    check_recovery_by_save();
}

static void test_one_copy_corrupt(void)
{
    store(STORED_GAIN, STORED_OFFSET);
    store(STORED_GAIN, STORED_OFFSET);
    calib_payload(1)[30] ^= 0x10u; /* copy B, a serial byte */
    check_boot("calib_one_copy", HD_FAULT_CALIB_ONE_COPY, 1, STORED_GAIN, STORED_OFFSET);
}

static void test_wrong_version(void)
{
    store(STORED_GAIN, STORED_OFFSET);
    uint8_t *p = calib_payload(0);
    TEST_ASSERT_EQUAL_UINT32(crc32_ref(p, 60), (uint32_t)(p[60] | p[61] << 8 | p[62] << 16 |
                                                          (uint32_t)p[63] << 24));
    /* an intact record of format version 2, stored as the store stores any */
    uint8_t rec[64];
    memcpy(rec, p, 64);
    rec[4] = 2;
    rec[5] = 0;
    uint32_t c = crc32_ref(rec, 60);
    rec[60] = (uint8_t)c;
    rec[61] = (uint8_t)(c >> 8);
    rec[62] = (uint8_t)(c >> 16);
    rec[63] = (uint8_t)(c >> 24);
    hd_calib_storage_t st = storage(&hal);
    TEST_ASSERT_EQUAL_INT(HD_RECORD_OK, hd_store_save(&st, HD_RECORD_KIND_CALIB,
                                                      HD_CALIB_RECORD_VERSION, rec, sizeof rec));
    check_boot("calib_wrong_version", HD_FAULT_CALIB_CORRUPT, 4, NOMINAL_GAIN, 0.0);
    check_recovery_by_save();
}

static void test_nvm_io_error(void)
{
    store(STORED_GAIN, STORED_OFFSET);
    mock.nvm_fail = true;
    check_boot("calib_nvm_error", HD_FAULT_CALIB_CORRUPT, 5, NOMINAL_GAIN, 0.0);
    mock.nvm_fail = false;
    check_recovery_by_save();
}

/* A record with a valid CRC but a gain no bridge chain has (a buggy tool
 * wrote it): counted as corrupt, defaults used. */
static void test_implausible_gain_record(void)
{
    store(3.4e38f, STORED_OFFSET);
    store(3.4e38f, STORED_OFFSET);
    check_boot("calib_implausible_gain", HD_FAULT_CALIB_CORRUPT, 3, NOMINAL_GAIN, 0.0);
    check_recovery_by_save();
}

/* ----------------------------------------------- power loss during a save */

typedef struct {
    hal_mock_t *m;
    const hal_t *inner;
    long budget; /* bytes that still reach the flash; < 0: unlimited */
    long used;
} cut_nvm_t;

static int cut_read(void *ctx, size_t off, void *buf, size_t len)
{
    cut_nvm_t *c = ctx;
    if (c->budget == 0) {
        return HAL_ERR_IO; /* power is gone */
    }
    return c->inner->nvm.read(c->inner->nvm.ctx, off, buf, len);
}

/* Byte by byte, so the power can fail after any one of them. */
static int cut_write(void *ctx, size_t off, const void *buf, size_t len)
{
    cut_nvm_t *c = ctx;
    for (size_t i = 0; i < len; i++) {
        if (c->budget == 0) {
            return HAL_ERR_IO;
        }
        int rc = c->inner->nvm.write(c->inner->nvm.ctx, off + i, (const uint8_t *)buf + i, 1);
        if (rc != HAL_OK) {
            return rc;
        }
        c->budget = c->budget > 0 ? c->budget - 1 : c->budget;
        c->used++;
    }
    return HAL_OK;
}

static int cut_erase(void *ctx, size_t off, size_t len)
{
    cut_nvm_t *c = ctx;
    for (size_t i = 0; i < len; i++) {
        if (c->budget == 0) {
            return HAL_ERR_IO;
        }
        int rc = c->inner->nvm.erase(c->inner->nvm.ctx, off + i, 1);
        if (rc != HAL_OK) {
            return rc;
        }
        c->budget = c->budget > 0 ? c->budget - 1 : c->budget;
        c->used++;
    }
    return HAL_OK;
}

/* The mock's NVM behind a power switch (cut->budget bytes still reach the
 * flash, < 0: all); returns the HAL that uses it. */
static const hal_t *cut_power(cut_nvm_t *cut)
{
    static hal_t cut_hal;
    cut->m = &mock;
    cut->inner = &hal;
    cut->budget = -1;
    cut->used = 0;
    cut_hal = hal;
    cut_hal.nvm.ctx = cut;
    cut_hal.nvm.read = cut_read;
    cut_hal.nvm.write = cut_write;
    cut_hal.nvm.erase = cut_erase;
    return &cut_hal;
}

/* Boots on `hal` with a stored record (gain 6.0), sets gain 7.0 over CAN,
 * sends CALIB_SAVE, and lets the power fail after `budget` flash bytes
 * (erase or write).  Returns the bytes used. */
static long save_with_power_cut(long budget)
{
    hal_mock_init(&mock);
    hal_mock_bind(&mock, &hal);
    store(STORED_GAIN, STORED_OFFSET);
    static cut_nvm_t cut;
    const hal_t *cut_hal = cut_power(&cut);
    TEST_ASSERT_EQUAL_INT(HD_FW_OK, hd_fw_init(&fw, cut_hal, &cfg));
    uint8_t set[8] = {0x20, 1, 12, 0, 0, 0, 0, 0};
    float g = NEW_GAIN;
    memcpy(&set[4], &g, 4); /* little-endian host */
    hal_can_frame_t f = {0x01D01001u, 8, HAL_CAN_FLAG_EXT, {0}};
    memcpy(f.data, set, 8);
    TEST_ASSERT_EQUAL_INT(0, hal_mock_push_rx(&mock, &f));
    hal_can_frame_t save = {0x01D01001u, 8, HAL_CAN_FLAG_EXT, {0x31, 2, 0, 0, 1, 0, 0, 0}};
    TEST_ASSERT_EQUAL_INT(0, hal_mock_push_rx(&mock, &save));
    TEST_ASSERT_EQUAL_INT(0, hal_mock_push(&mock, COUNTS, 0));
    hd_fw_isr(&fw);          /* queues both commands */
    hd_fw_background(&fw);   /* the new gain, waiting for the tick */
    TEST_ASSERT_EQUAL_INT(0, hal_mock_push(&mock, COUNTS, 0));
    hd_fw_isr(&fw);          /* makes it live */
    cut.budget = budget;
    hd_fw_background(&fw);   /* the write, cut by the power loss */
    return cut.used;
}

static void test_power_loss_at_every_byte_of_a_save(void)
{
    long total = save_with_power_cut(-1);
    TEST_ASSERT_TRUE(total >= 64);
    unsigned old_seen = 0, new_seen = 0;
    bool switched = false;
    for (long k = 0; k <= total; k++) {
        save_with_power_cut(k);
        /* reboot on the plain NVM */
        TEST_ASSERT_EQUAL_INT(HD_FW_OK, hd_fw_init(&fw, &hal, &cfg));
        int st = hd_fw_record_status(&fw, HD_RECORD_KIND_CALIB);
        TEST_ASSERT_TRUE(st == HD_RECORD_OK || st == HD_RECORD_ONE_COPY_BAD);
        TEST_ASSERT_EQUAL_UINT32(0, fw.settings[fw.live_settings].record_faults &
                                        (HD_FAULT_CALIB_MISSING | HD_FAULT_CALIB_CORRUPT));
        const float gain = hd_fw_config(&fw)->calib_gain_nm_per_v;
        if (gain == STORED_GAIN) {
            TEST_ASSERT_FALSE_MESSAGE(switched, "old record came back after the new one");
            old_seen++;
        } else {
            TEST_ASSERT_EQUAL_FLOAT(NEW_GAIN, gain);
            switched = true;
            new_seen++;
        }
    }
    TEST_ASSERT_EQUAL_FLOAT(NEW_GAIN, hd_fw_config(&fw)->calib_gain_nm_per_v); /* complete save */
    TEST_ASSERT_TRUE(old_seen > 0 && new_seen > 0);
    rel_measured("calib_power_loss", "cut_points=%ld old=%u new=%u", total + 1, old_seen, new_seen);
}

/* ------------------------------------- power loss during a PROFILE_SAVE */

#define OLD_A_NM 0.5f
#define NEW_A_NM 0.9f

static void store_profile(hd_store_io_t *io, float a_nm)
{
    hd_profile_record_t r;
    memset(&r, 0, sizeof r);
    r.gear_ratio = cfg.gear_ratio;
    r.motor_cpr = cfg.motor_cpr;
    r.output_cpr = cfg.output_cpr;
    r.profile.line_count = 3;
    const uint8_t order[3] = {2, 4, 1};
    for (unsigned i = 0; i < 3; i++) {
        r.profile.lines[i].lock = i == 2 ? HD_KF_LOCK_OUTPUT : HD_KF_LOCK_MOTOR;
        r.profile.lines[i].order = order[i];
        r.profile.lines[i].a_nm = a_nm;
        r.profile.lines[i].b_nm = -0.25f;
    }
    uint8_t buf[HD_PROFILE_RECORD_MAX];
    size_t len = hd_profile_record_encode(&r, buf, sizeof buf);
    TEST_ASSERT_EQUAL_INT(HD_RECORD_OK, hd_store_save(io, HD_RECORD_KIND_PROFILE,
                                                      HD_PROFILE_RECORD_VERSION, buf, len));
}

static void push_cmd(uint8_t op, uint8_t b2, uint8_t b3, float v)
{
    hal_can_frame_t f = {0x01D01001u, 8, HAL_CAN_FLAG_EXT, {op, 7, b2, b3, 0, 0, 0, 0}};
    memcpy(&f.data[4], &v, 4); /* little-endian host */
    TEST_ASSERT_EQUAL_INT(0, hal_mock_push_rx(&mock, &f));
}

/* Boots with a stored profile (a = 0.5), uploads one with a = 0.9 over CAN,
 * sends PROFILE_SAVE (the uploaded lines) and lets the power fail after
 * `budget` flash bytes.  Returns the bytes used. */
static long profile_save_with_power_cut(long budget)
{
    hal_mock_init(&mock);
    hal_mock_bind(&mock, &hal);
    hd_calib_storage_t plain = storage(&hal);
    store_profile(&plain, OLD_A_NM);
    static cut_nvm_t cut;
    const hal_t *cut_hal = cut_power(&cut);
    TEST_ASSERT_EQUAL_INT(HD_FW_OK, hd_fw_init(&fw, cut_hal, &cfg));
    const uint8_t order[3] = {2, 4, 1};
    for (unsigned i = 0; i < 3; i++) {
        const uint8_t out = i == 2 ? 0x20u : 0u;
        push_cmd(HD_CMD_PROFILE_PUT, (uint8_t)(i | out), order[i], NEW_A_NM);
        push_cmd(HD_CMD_PROFILE_PUT, (uint8_t)(i | out | 0x10u), order[i], -0.25f);
    }
    tick(4); /* queued and handled (no NVM) */
    push_cmd(HD_CMD_PROFILE_SAVE, 1, 0, 0.0f);
    TEST_ASSERT_EQUAL_INT(0, hal_mock_push(&mock, COUNTS, 0));
    hd_fw_isr(&fw);        /* queues it */
    cut.budget = budget;
    hd_fw_background(&fw); /* the write, cut by the power loss */
    return cut.used;
}

static void test_profile_power_loss_at_every_byte_of_a_save(void)
{
    long total = profile_save_with_power_cut(-1);
    TEST_ASSERT_TRUE(total >= HD_PROFILE_RECORD_HEADER + 3 * HD_PROFILE_RECORD_LINE);
    unsigned old_seen = 0, new_seen = 0;
    bool switched = false;
    for (long k = 0; k <= total; k++) {
        profile_save_with_power_cut(k);
        TEST_ASSERT_EQUAL_INT(HD_FW_OK, hd_fw_init(&fw, &hal, &cfg)); /* reboot */
        int st = hd_fw_record_status(&fw, HD_RECORD_KIND_PROFILE);
        TEST_ASSERT_TRUE(st == HD_RECORD_OK || st == HD_RECORD_ONE_COPY_BAD);
        TEST_ASSERT_EQUAL_UINT32(0, fw.settings[fw.live_settings].record_faults &
                                        HD_FAULT_PROFILE_UNUSABLE);
        TEST_ASSERT_EQUAL_UINT8(3, fw.bg.profile.line_count);
        const float a = fw.bg.profile.lines[0].a_nm;
        if (a == OLD_A_NM) {
            TEST_ASSERT_FALSE_MESSAGE(switched, "old profile came back after the new one");
            old_seen++;
        } else {
            TEST_ASSERT_EQUAL_FLOAT(NEW_A_NM, a);
            switched = true;
            new_seen++;
        }
    }
    TEST_ASSERT_EQUAL_FLOAT(NEW_A_NM, fw.bg.profile.lines[0].a_nm); /* complete save */
    TEST_ASSERT_TRUE(old_seen > 0 && new_seen > 0);
    rel_measured("profile_power_loss", "cut_points=%ld old=%u new=%u", total + 1, old_seen,
                 new_seen);
}

int main(int argc, char **argv)
{
    if (UnityParseOptions(argc, argv) != 0) {
        return 1;
    }
    UNITY_BEGIN();
    RUN_TEST(test_missing_record);
    RUN_TEST(test_crc_corrupt_both_copies);
    RUN_TEST(test_one_copy_corrupt);
    RUN_TEST(test_wrong_version);
    RUN_TEST(test_nvm_io_error);
    RUN_TEST(test_implausible_gain_record);
    RUN_TEST(test_power_loss_at_every_byte_of_a_save);
    RUN_TEST(test_profile_power_loss_at_every_byte_of_a_save);
    return UNITY_END();
}
