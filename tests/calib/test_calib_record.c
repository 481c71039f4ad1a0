/* Calibration record: encoding, and its life in the record store (the
 * store itself: test_record_store.c). */
#include "flash_sim.h"
#include "hd_calib_record.h"
#include "unity.h"

#include <math.h>
#include <string.h>

static flash_sim_t g_flash;
static hd_calib_storage_t g_st;

void setUp(void)
{
    g_st = flash_sim_reset(&g_flash);
}

void tearDown(void) {}

static hd_calib_record_t make_rec(float gain, const char *serial)
{
    hd_calib_record_t r;
    memset(&r, 0, sizeof r);
    r.gain_nm_per_v = gain;
    r.offset_v = -0.0123f;
    r.calibrated_unix_s = 1700000000u;
    strncpy(r.serial, serial, sizeof r.serial - 1u);
    r.consistency = 0.02f;
    return r;
}

static int rec_equal(const hd_calib_record_t *a, const hd_calib_record_t *b)
{
    return a->gain_nm_per_v == b->gain_nm_per_v && a->offset_v == b->offset_v &&
           a->calibrated_unix_s == b->calibrated_unix_s &&
           memcmp(a->serial, b->serial, sizeof a->serial) == 0 &&
           a->consistency == b->consistency;
}

static void test_defaults_are_nominal(void)
{
    hd_calib_record_t r;
    memset(&r, 0x5A, sizeof r);
    hd_calib_record_default(&r);
    TEST_ASSERT_EQUAL_FLOAT(6.60f, r.gain_nm_per_v); /* Table I of the paper */
    TEST_ASSERT_EQUAL_FLOAT(0.0f, r.offset_v);
    TEST_ASSERT_EQUAL_UINT32(0u, r.calibrated_unix_s);
    TEST_ASSERT_EQUAL_UINT8(0u, (uint8_t)r.serial[0]);
}

static void test_encode_layout_and_roundtrip(void)
{
    hd_calib_record_t r = make_rec(6.61f, "HD-0001");
    uint8_t buf[HD_CALIB_RECORD_BYTES + 8];
    TEST_ASSERT_EQUAL_UINT(HD_CALIB_RECORD_BYTES, hd_calib_record_encode(&r, 7u, buf, sizeof buf));
    /* Layout of docs/how-to/calibration.md, checked byte by byte. */
    TEST_ASSERT_EQUAL_UINT8('H', buf[0]);
    TEST_ASSERT_EQUAL_UINT8('D', buf[1]);
    TEST_ASSERT_EQUAL_UINT8('C', buf[2]);
    TEST_ASSERT_EQUAL_UINT8('R', buf[3]);
    TEST_ASSERT_EQUAL_UINT8(1u, buf[4]);
    TEST_ASSERT_EQUAL_UINT8(0u, buf[5]);
    TEST_ASSERT_EQUAL_UINT8(64u, buf[6]);
    TEST_ASSERT_EQUAL_UINT8(7u, buf[8]);
    float g;
    memcpy(&g, buf + 12, 4); /* host is little-endian */
    TEST_ASSERT_EQUAL_FLOAT(6.61f, g);
    TEST_ASSERT_EQUAL_MEMORY("HD-0001", buf + 24, 8);
    uint32_t crc = (uint32_t)buf[60] | ((uint32_t)buf[61] << 8) | ((uint32_t)buf[62] << 16) |
                   ((uint32_t)buf[63] << 24);
    TEST_ASSERT_EQUAL_HEX32(hd_crc32(buf, 60), crc);

    hd_calib_record_t back;
    uint32_t seq = 0;
    TEST_ASSERT_EQUAL_INT(0, hd_calib_record_decode(buf, HD_CALIB_RECORD_BYTES, &back, &seq));
    TEST_ASSERT_EQUAL_UINT32(7u, seq);
    TEST_ASSERT_TRUE(rec_equal(&r, &back));
}

static void test_encode_rejects_bad_values(void)
{
    uint8_t buf[HD_CALIB_RECORD_BYTES];
    hd_calib_record_t r = make_rec(6.6f, "X");
    TEST_ASSERT_EQUAL_UINT(0u, hd_calib_record_encode(&r, 1u, buf, sizeof buf - 1u));
    TEST_ASSERT_EQUAL_UINT(0u, hd_calib_record_encode(NULL, 1u, buf, sizeof buf));
    r.gain_nm_per_v = NAN;
    TEST_ASSERT_EQUAL_UINT(0u, hd_calib_record_encode(&r, 1u, buf, sizeof buf));
    r.gain_nm_per_v = -6.6f;
    TEST_ASSERT_EQUAL_UINT(0u, hd_calib_record_encode(&r, 1u, buf, sizeof buf));
    r = make_rec(6.6f, "X");
    r.offset_v = INFINITY;
    TEST_ASSERT_EQUAL_UINT(0u, hd_calib_record_encode(&r, 1u, buf, sizeof buf));
}

static void test_every_single_bit_flip_is_detected(void)
{
    hd_calib_record_t r = make_rec(6.6f, "SER");
    uint8_t buf[HD_CALIB_RECORD_BYTES];
    hd_calib_record_encode(&r, 3u, buf, sizeof buf);
    for (unsigned byte = 0; byte < HD_CALIB_RECORD_BYTES; ++byte) {
        for (unsigned bit = 0; bit < 8u; ++bit) {
            uint8_t bad[HD_CALIB_RECORD_BYTES];
            memcpy(bad, buf, sizeof bad);
            bad[byte] ^= (uint8_t)(1u << bit);
            hd_calib_record_t out = make_rec(1.0f, "untouched");
            int rc = hd_calib_record_decode(bad, sizeof bad, &out, NULL);
            TEST_ASSERT_EQUAL_INT(HD_RECORD_CORRUPT, rc);
            TEST_ASSERT_EQUAL_FLOAT(1.0f, out.gain_nm_per_v); /* not written on error */
        }
    }
}

static void test_other_version_is_reported(void)
{
    hd_calib_record_t r = make_rec(6.6f, "V2");
    uint8_t buf[HD_CALIB_RECORD_BYTES];
    hd_calib_record_encode(&r, 1u, buf, sizeof buf);
    buf[4] = 2u; /* a future format, with a valid CRC */
    uint32_t crc = hd_crc32(buf, 60);
    for (unsigned i = 0; i < 4u; ++i) {
        buf[60 + i] = (uint8_t)(crc >> (8u * i));
    }
    hd_calib_record_t out;
    TEST_ASSERT_EQUAL_INT(HD_RECORD_BAD_VERSION, hd_calib_record_decode(buf, sizeof buf, &out, NULL));
    /* In the store: defaults, BAD_VERSION. */
    TEST_ASSERT_EQUAL_INT(HD_RECORD_OK, hd_store_save(&g_st, HD_RECORD_KIND_CALIB,
                                                      HD_CALIB_RECORD_VERSION, buf, sizeof buf));
    uint32_t seq = 99u;
    TEST_ASSERT_EQUAL_INT(HD_RECORD_BAD_VERSION, hd_calib_store_load(&g_st, &out, &seq));
    TEST_ASSERT_EQUAL_FLOAT(6.60f, out.gain_nm_per_v);
    TEST_ASSERT_EQUAL_UINT32(0u, seq);
}

static void test_blank_storage_is_missing_with_defaults(void)
{
    hd_calib_record_t out = make_rec(1.0f, "junk");
    TEST_ASSERT_EQUAL_INT(HD_RECORD_MISSING, hd_calib_store_load(&g_st, &out, NULL));
    TEST_ASSERT_EQUAL_FLOAT(6.60f, out.gain_nm_per_v);
    TEST_ASSERT_EQUAL_FLOAT(0.0f, out.offset_v);
}

static void test_garbage_storage_is_corrupt_with_defaults(void)
{
    for (unsigned i = 0; i < FLASH_SIM_BYTES; ++i) {
        g_flash.mem[i] = (uint8_t)(i * 37u + 11u);
    }
    hd_calib_record_t out = make_rec(1.0f, "junk");
    TEST_ASSERT_EQUAL_INT(HD_RECORD_CORRUPT, hd_calib_store_load(&g_st, &out, NULL));
    TEST_ASSERT_EQUAL_FLOAT(6.60f, out.gain_nm_per_v);
}

static void test_read_error_gives_defaults(void)
{
    hd_calib_record_t r = make_rec(6.5f, "A");
    TEST_ASSERT_EQUAL_INT(HD_RECORD_OK, hd_calib_store_save(&g_st, &r));
    g_flash.fail_read = 1;
    hd_calib_record_t out;
    TEST_ASSERT_EQUAL_INT(HD_RECORD_IO, hd_calib_store_load(&g_st, &out, NULL));
    TEST_ASSERT_EQUAL_FLOAT(6.60f, out.gain_nm_per_v);
    TEST_ASSERT_EQUAL_INT(HD_RECORD_IO, hd_calib_store_save(&g_st, &r));
    TEST_ASSERT_EQUAL_INT(HD_RECORD_IO, hd_calib_store_load(NULL, &out, NULL));
}

static void test_saves_alternate_and_newest_wins(void)
{
    hd_calib_record_t a = make_rec(6.50f, "A"), b = make_rec(6.70f, "B"), c = make_rec(6.60f, "C");
    hd_calib_record_t out;
    uint32_t seq;
    TEST_ASSERT_EQUAL_INT(HD_RECORD_OK, hd_calib_store_save(&g_st, &a));
    TEST_ASSERT_EQUAL_INT(HD_RECORD_OK, hd_calib_store_load(&g_st, &out, &seq));
    TEST_ASSERT_TRUE(rec_equal(&a, &out));
    TEST_ASSERT_EQUAL_UINT32(1u, seq);
    TEST_ASSERT_EQUAL_INT(HD_RECORD_OK, hd_calib_store_save(&g_st, &b));
    TEST_ASSERT_EQUAL_INT(HD_RECORD_OK, hd_calib_store_save(&g_st, &c));
    TEST_ASSERT_EQUAL_INT(HD_RECORD_OK, hd_calib_store_load(&g_st, &out, &seq));
    TEST_ASSERT_TRUE(rec_equal(&c, &out));
    TEST_ASSERT_EQUAL_UINT32(3u, seq);
    /* Damage the newest record's gain (copy A, sequence 3): B's record
     * (sequence 2) is used, flagged. */
    size_t off = hd_le_get_u16(g_flash.mem + 16 + 4);
    g_flash.mem[off + 12] ^= 0x40u;
    TEST_ASSERT_EQUAL_INT(HD_RECORD_ONE_COPY_BAD, hd_calib_store_load(&g_st, &out, &seq));
    TEST_ASSERT_TRUE(rec_equal(&b, &out));
    TEST_ASSERT_EQUAL_UINT32(2u, seq);
}

static void test_intact_but_implausible_bytes_are_corrupt(void)
{
    /* A store entry whose CRC is right but whose 64 bytes are not a record
     * (written by a bug) is refused, with defaults. */
    uint8_t junk[HD_CALIB_RECORD_BYTES];
    memset(junk, 0x11, sizeof junk);
    TEST_ASSERT_EQUAL_INT(HD_RECORD_OK, hd_store_save(&g_st, HD_RECORD_KIND_CALIB,
                                                      HD_CALIB_RECORD_VERSION, junk, sizeof junk));
    hd_calib_record_t out;
    TEST_ASSERT_EQUAL_INT(HD_RECORD_CORRUPT, hd_calib_store_load(&g_st, &out, NULL));
    TEST_ASSERT_EQUAL_FLOAT(6.60f, out.gain_nm_per_v);
}

/* Interrupt one save at every byte (erase bytes included) from a given
 * starting state; after "power returns" the load must give exactly the old
 * newest record or the new one, never defaults or garbage. */
static void power_loss_sweep(int n_before)
{
    hd_calib_record_t old_r = make_rec(6.55f, "OLD"), new_r = make_rec(6.65f, "NEW");
    long total = -1;
    long saw_old = 0, saw_new = 0;
    for (long k = 0; total < 0; ++k) {
        setUp();
        for (int i = 0; i < n_before; ++i) {
            hd_calib_record_t filler = (i == n_before - 1) ? old_r : make_rec(6.1f + 0.1f * (float)i, "F");
            TEST_ASSERT_EQUAL_INT(HD_RECORD_OK, hd_calib_store_save(&g_st, &filler));
        }
        g_flash.budget = k;
        int rc = hd_calib_store_save(&g_st, &new_r);
        g_flash.budget = -1;
        if (rc == HD_RECORD_OK) {
            total = k;
        }
        hd_calib_record_t out;
        hd_record_status_t st = hd_calib_store_load(&g_st, &out, NULL);
        if (n_before == 0 && total < 0) {
            /* Nothing was ever stored: missing (or a half-written copy) with defaults. */
            TEST_ASSERT_TRUE(st == HD_RECORD_MISSING || st == HD_RECORD_CORRUPT);
            TEST_ASSERT_EQUAL_FLOAT(6.60f, out.gain_nm_per_v);
            continue;
        }
        TEST_ASSERT_TRUE_MESSAGE(st == HD_RECORD_OK || st == HD_RECORD_ONE_COPY_BAD,
                                 "a valid copy must survive");
        if (rec_equal(&out, &old_r)) {
            saw_old++;
        } else {
            TEST_ASSERT_TRUE_MESSAGE(rec_equal(&out, &new_r), "neither old nor new record");
            saw_new++;
            /* The new record is only visible once completely written. */
            TEST_ASSERT_EQUAL_INT(total, k);
        }
    }
    TEST_ASSERT_TRUE(total > (long)(FLASH_SIM_BYTES / 2u)); /* crossed erase and writes */
    if (n_before > 0) {
        TEST_ASSERT_EQUAL_INT(total, saw_old);
        TEST_ASSERT_EQUAL_INT(1, saw_new);
    }
}

static void test_power_loss_first_save(void) { power_loss_sweep(0); }
static void test_power_loss_one_copy_present(void) { power_loss_sweep(1); }
static void test_power_loss_both_copies_present(void) { power_loss_sweep(2); }
static void test_power_loss_many_saves(void) { power_loss_sweep(5); }

int main(int argc, char **argv)
{
    if (UnityParseOptions(argc, argv) != 0) {
        return 1;
    }
    UNITY_BEGIN();
    RUN_TEST(test_defaults_are_nominal);
    RUN_TEST(test_encode_layout_and_roundtrip);
    RUN_TEST(test_encode_rejects_bad_values);
    RUN_TEST(test_every_single_bit_flip_is_detected);
    RUN_TEST(test_other_version_is_reported);
    RUN_TEST(test_blank_storage_is_missing_with_defaults);
    RUN_TEST(test_garbage_storage_is_corrupt_with_defaults);
    RUN_TEST(test_read_error_gives_defaults);
    RUN_TEST(test_saves_alternate_and_newest_wins);
    RUN_TEST(test_intact_but_implausible_bytes_are_corrupt);
    RUN_TEST(test_power_loss_first_save);
    RUN_TEST(test_power_loss_one_copy_present);
    RUN_TEST(test_power_loss_both_copies_present);
    RUN_TEST(test_power_loss_many_saves);
    return UNITY_END();
}
