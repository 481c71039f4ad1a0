/* The record store: layout, per-record fallback, removal, carrying records
 * forward, corruption of every bit, and power loss at every byte. */
#include "flash_sim.h"
#include "hd_record_store.h"
#include "unity.h"

#include <stdbool.h>
#include <string.h>

static flash_sim_t g_flash;
static hd_store_io_t g_io;

#define HALF (FLASH_SIM_BYTES / 2u)

void setUp(void)
{
    g_io = flash_sim_reset(&g_flash);
}

void tearDown(void) {}

/* A payload whose bytes depend on kind and tag, so mix-ups show. */
static void payload(uint8_t kind, uint8_t tag, uint8_t *buf, size_t len)
{
    for (size_t i = 0; i < len; ++i) {
        buf[i] = (uint8_t)(kind * 71u + tag * 13u + i * 7u);
    }
}

static void save(uint8_t kind, uint8_t tag, size_t len)
{
    uint8_t p[300];
    payload(kind, tag, p, len);
    TEST_ASSERT_EQUAL_INT(HD_RECORD_OK, hd_store_save(&g_io, kind, 1u, p, len));
}

/* Loads kind and checks it holds (kind, tag, len); returns the status. */
static hd_record_status_t expect(uint8_t kind, uint8_t tag, size_t len)
{
    uint8_t got[300];
    uint8_t want[300];
    size_t n = 0;
    hd_record_status_t st = hd_store_load(&g_io, kind, 1u, got, sizeof got, &n, NULL, NULL);
    TEST_ASSERT_TRUE_MESSAGE(st == HD_RECORD_OK || st == HD_RECORD_ONE_COPY_BAD, "not loaded");
    payload(kind, tag, want, len);
    TEST_ASSERT_EQUAL_UINT(len, n);
    TEST_ASSERT_EQUAL_MEMORY(want, got, len);
    return st;
}

static hd_record_status_t status_of(uint8_t kind)
{
    uint8_t got[300];
    size_t n = 0;
    return hd_store_load(&g_io, kind, 1u, got, sizeof got, &n, NULL, NULL);
}

static void test_crc32_check_value(void)
{
    /* The published check value of CRC-32/ISO-HDLC (zlib). */
    TEST_ASSERT_EQUAL_HEX32(0xCBF43926u, hd_crc32("123456789", 9));
    TEST_ASSERT_EQUAL_HEX32(0x00000000u, hd_crc32("", 0));
    uint32_t c = hd_crc32_update(0u, "1234", 4);
    TEST_ASSERT_EQUAL_HEX32(0xCBF43926u, hd_crc32_update(c, "56789", 5));
}

static void test_blank_is_missing_and_garbage_is_corrupt(void)
{
    TEST_ASSERT_EQUAL_INT(HD_RECORD_MISSING, status_of(1));
    for (unsigned i = 0; i < FLASH_SIM_BYTES; ++i) {
        g_flash.mem[i] = (uint8_t)(i * 37u + 11u);
    }
    TEST_ASSERT_EQUAL_INT(HD_RECORD_CORRUPT, status_of(1));
}

static void test_layout_as_documented(void)
{
    save(2, 5, 10);
    const uint8_t *c = g_flash.mem; /* the first save goes to copy A */
    TEST_ASSERT_EQUAL_MEMORY("HDST", c, 4);
    TEST_ASSERT_EQUAL_UINT16(HD_STORE_FORMAT, hd_le_get_u16(c + 4));
    TEST_ASSERT_EQUAL_UINT32(1u, hd_le_get_u32(c + 8));   /* sequence */
    TEST_ASSERT_EQUAL_UINT8(1u, c[12]);                    /* one record */
    const uint8_t *e = c + 16;                             /* its directory entry */
    TEST_ASSERT_EQUAL_UINT8(2u, e[0]);
    TEST_ASSERT_EQUAL_UINT16(1u, hd_le_get_u16(e + 2));    /* version */
    uint16_t off = hd_le_get_u16(e + 4);
    TEST_ASSERT_EQUAL_UINT16(10u, hd_le_get_u16(e + 6));
    TEST_ASSERT_EQUAL_HEX32(hd_crc32(c + off, 10), hd_le_get_u32(e + 8));
    TEST_ASSERT_EQUAL_HEX32(hd_crc32(c + 4, 24), hd_le_get_u32(c + 28)); /* header CRC */
    uint8_t want[10];
    payload(2, 5, want, 10);
    TEST_ASSERT_EQUAL_MEMORY(want, c + off, 10);
    TEST_ASSERT_EQUAL_UINT16(off + 10u, hd_le_get_u16(c + 6)); /* image length */
    TEST_ASSERT_EQUAL_UINT8(0xFFu, g_flash.mem[HALF]);          /* copy B untouched */
}

static void test_saves_alternate_and_carry_the_others(void)
{
    save(1, 1, 64);
    save(2, 1, 100);
    save(3, 1, 7);
    save(2, 2, 120); /* the fourth save: kinds 1 and 3 come along */
    TEST_ASSERT_EQUAL_INT(HD_RECORD_OK, expect(1, 1, 64));
    TEST_ASSERT_EQUAL_INT(HD_RECORD_OK, expect(2, 2, 120));
    TEST_ASSERT_EQUAL_INT(HD_RECORD_OK, expect(3, 1, 7));
    uint32_t seq = 0;
    uint8_t buf[300];
    size_t n;
    TEST_ASSERT_EQUAL_INT(HD_RECORD_OK, hd_store_load(&g_io, 2, 1u, buf, sizeof buf, &n, &seq, NULL));
    TEST_ASSERT_EQUAL_UINT32(4u, seq);
    TEST_ASSERT_EQUAL_UINT32(4u, hd_le_get_u32(g_flash.mem + HALF + 8)); /* 2nd, 4th: copy B */
    TEST_ASSERT_EQUAL_UINT32(3u, hd_le_get_u32(g_flash.mem + 8));
}

static void test_removed_record_does_not_come_back(void)
{
    save(3, 1, 40);
    save(1, 1, 64);
    TEST_ASSERT_EQUAL_INT(HD_RECORD_OK, hd_store_save(&g_io, 3, 1u, NULL, 0));
    /* The older copy still holds kind 3; the newest says it is gone. */
    TEST_ASSERT_EQUAL_INT(HD_RECORD_MISSING, status_of(3));
    TEST_ASSERT_EQUAL_INT(HD_RECORD_OK, expect(1, 1, 64));
}

static void test_bad_payload_in_newest_falls_back_per_record(void)
{
    save(1, 1, 64);
    save(2, 1, 50);
    save(1, 2, 64); /* copy A: kinds 1 (tag 2) and 2; copy B: kinds 1 (tag 1), 2 */
    uint16_t off = hd_le_get_u16(g_flash.mem + 16 + 4 + 12); /* second entry: kind 1? */
    uint8_t kind_at_1 = g_flash.mem[16 + 12];
    TEST_ASSERT_EQUAL_UINT8(1u, kind_at_1); /* carried records first, the saved one last */
    g_flash.mem[off + 3] ^= 0x10u;
    TEST_ASSERT_EQUAL_INT(HD_RECORD_ONE_COPY_BAD, expect(1, 1, 64)); /* the older copy's */
    TEST_ASSERT_EQUAL_INT(HD_RECORD_OK, expect(2, 1, 50));
}

static void test_a_record_only_intact_in_the_half_being_erased_survives(void)
{
    save(2, 1, 50);   /* A */
    save(1, 1, 64);   /* B: kinds 2, 1 */
    /* Damage kind 2 in the newest copy (B): its only intact copy is in A,
     * which the next save erases. */
    uint16_t off = hd_le_get_u16(g_flash.mem + HALF + 16 + 4);
    TEST_ASSERT_EQUAL_UINT8(2u, g_flash.mem[HALF + 16]);
    g_flash.mem[HALF + off] ^= 0x01u;
    save(3, 1, 9);    /* writes A */
    /* Intact in the new copy; B still holds the damaged one. */
    TEST_ASSERT_EQUAL_INT(HD_RECORD_ONE_COPY_BAD, expect(2, 1, 50));
    TEST_ASSERT_EQUAL_INT(HD_RECORD_OK, expect(1, 1, 64));
    TEST_ASSERT_EQUAL_INT(HD_RECORD_OK, expect(3, 1, 9));
}

static void test_other_version_is_reported_not_used(void)
{
    uint8_t p[20];
    payload(1, 1, p, sizeof p);
    TEST_ASSERT_EQUAL_INT(HD_RECORD_OK, hd_store_save(&g_io, 1, 7u, p, sizeof p));
    uint8_t buf[64];
    size_t n = 0;
    uint16_t ver = 0;
    TEST_ASSERT_EQUAL_INT(HD_RECORD_BAD_VERSION,
                          hd_store_load(&g_io, 1, 1u, buf, sizeof buf, &n, NULL, &ver));
    TEST_ASSERT_EQUAL_UINT16(7u, ver);
}

static void test_every_bit_flip_of_the_newest_copy(void)
{
    save(1, 1, 64);
    save(2, 1, 30);
    save(1, 2, 64);
    save(2, 2, 30); /* newest: copy B (seq 4) kinds 1 tag 2, 2 tag 2; A: 1 tag 2, 2 tag 1 */
    uint8_t clean[FLASH_SIM_BYTES];
    memcpy(clean, g_flash.mem, sizeof clean);
    size_t used = hd_le_get_u16(g_flash.mem + HALF + 6);
    unsigned fallbacks = 0;
    for (size_t byte = 0; byte < used; ++byte) {
        for (unsigned bit = 0; bit < 8u; ++bit) {
            memcpy(g_flash.mem, clean, sizeof clean);
            g_flash.mem[HALF + byte] ^= (uint8_t)(1u << bit);
            /* Each record is the newest version or, flagged, the older one;
             * never a damaged payload and never lost. */
            uint8_t got[300];
            size_t n = 0;
            hd_record_status_t st = hd_store_load(&g_io, 2, 1u, got, sizeof got, &n, NULL, NULL);
            uint8_t want_new[30], want_old[30];
            payload(2, 2, want_new, 30);
            payload(2, 1, want_old, 30);
            TEST_ASSERT_TRUE(st == HD_RECORD_OK || st == HD_RECORD_ONE_COPY_BAD);
            TEST_ASSERT_EQUAL_UINT(30u, n);
            bool is_new = memcmp(got, want_new, 30) == 0;
            TEST_ASSERT_TRUE(is_new || memcmp(got, want_old, 30) == 0);
            TEST_ASSERT_TRUE(is_new || st == HD_RECORD_ONE_COPY_BAD);
            fallbacks += !is_new;
            expect(1, 2, 64); /* tag 2 in both copies */
        }
    }
    TEST_ASSERT_TRUE(fallbacks > 0u);
}

static void test_storage_errors(void)
{
    save(1, 1, 64);
    g_flash.fail_read = 1;
    TEST_ASSERT_EQUAL_INT(HD_RECORD_IO, status_of(1));
    uint8_t p[8] = {0};
    TEST_ASSERT_EQUAL_INT(HD_RECORD_IO, hd_store_save(&g_io, 2, 1u, p, sizeof p));
    g_flash.fail_read = 0;
    g_flash.fail_write = 1;
    TEST_ASSERT_EQUAL_INT(HD_RECORD_IO, hd_store_save(&g_io, 2, 1u, p, sizeof p));
    g_flash.fail_write = 0;
    TEST_ASSERT_EQUAL_INT(HD_RECORD_OK, expect(1, 1, 64)); /* the old copy is intact */
    hd_store_io_t small = g_io;
    small.size = HD_STORE_MIN_SIZE - 2u;
    TEST_ASSERT_EQUAL_INT(HD_RECORD_IO, hd_store_save(&small, 2, 1u, p, sizeof p));
    hd_store_io_t no_work = g_io;
    no_work.work = NULL;
    TEST_ASSERT_EQUAL_INT(HD_RECORD_IO, hd_store_save(&no_work, 2, 1u, p, sizeof p));
    static uint8_t big[HD_STORE_IMAGE_MAX];
    TEST_ASSERT_EQUAL_INT(HD_RECORD_IO, hd_store_save(&g_io, 2, 1u, big, sizeof big));
    uint8_t tiny[4];
    size_t n;
    TEST_ASSERT_EQUAL_INT(HD_RECORD_CORRUPT, hd_store_load(&g_io, 1, 1u, tiny, sizeof tiny, &n, NULL, NULL));
}

static void test_sequence_wraps(void)
{
    save(1, 1, 16);
    save(1, 2, 16);
    /* Rewrite the sequence numbers to 0xFFFFFFFF (A) and 0 (B), fixing the
     * header CRCs: 0 is one more than 0xFFFFFFFF, so B is newer. */
    uint32_t seqs[2] = {0xFFFFFFFFu, 0u};
    for (unsigned h = 0; h < 2u; ++h) {
        uint8_t *c = g_flash.mem + h * HALF;
        hd_le_put_u32(c + 8, seqs[h]);
        hd_le_put_u32(c + 28, hd_crc32(c + 4, 24));
    }
    TEST_ASSERT_EQUAL_INT(HD_RECORD_OK, expect(1, 2, 16));
}

/* Interrupts one save at every byte (erase bytes included); after power
 * returns every record is exactly its old or (only once the save completed)
 * its new value. */
static void power_loss_sweep(unsigned n_before)
{
    const long erase = (long)HALF;
    long total = -1;
    long saw_new = 0;
    for (long k = 0;; ++k) {
        setUp();
        for (unsigned i = 0; i < n_before; ++i) {
            save((uint8_t)(1u + i % 3u), (uint8_t)i, 40u + i);
        }
        g_flash.budget = k;
        uint8_t p[90];
        payload(2, 200, p, sizeof p);
        hd_record_status_t st = hd_store_save(&g_io, 2, 1u, p, sizeof p);
        g_flash.budget = -1;
        if (st == HD_RECORD_OK) {
            total = k;
        }
        for (unsigned i = 0; i < n_before; ++i) {
            uint8_t kind = (uint8_t)(1u + i % 3u);
            if (kind == 2u || i + 3u < n_before) {
                continue; /* superseded by a later save of the same kind */
            }
            expect(kind, (uint8_t)i, 40u + i);
        }
        hd_record_status_t s2 = status_of(2);
        /* The half being written (A after an even number of saves) carries
         * the new sequence under a valid magic only once every other byte
         * is in (before the erase reaches it, its old image is intact). */
        const uint8_t *target = g_flash.mem + ((n_before % 2u == 0u) ? 0u : HALF);
        bool new_magic = hd_le_get_u32(target) == HD_STORE_MAGIC &&
                         hd_le_get_u32(target + 8) == n_before + 1u;
        TEST_ASSERT_TRUE((st == HD_RECORD_OK) == new_magic);
        if (st == HD_RECORD_OK) {
            expect(2, 200, sizeof p);
            saw_new++;
            break;
        }
        if (n_before >= 2u) {
            unsigned last2 = ((n_before - 2u) / 3u) * 3u + 1u; /* last i with kind 2 */
            TEST_ASSERT_TRUE(s2 == HD_RECORD_OK || s2 == HD_RECORD_ONE_COPY_BAD);
            expect(2, (uint8_t)last2, 40u + last2);
        } else {
            TEST_ASSERT_TRUE(s2 == HD_RECORD_MISSING || s2 == HD_RECORD_CORRUPT);
        }
    }
    TEST_ASSERT_EQUAL_INT(1, saw_new);
    TEST_ASSERT_TRUE(total > erase); /* the sweep crossed the erase and the writes */
}

static void test_power_loss_first_save(void) { power_loss_sweep(0); }
static void test_power_loss_one_record(void) { power_loss_sweep(1); }
static void test_power_loss_three_records(void) { power_loss_sweep(3); }
static void test_power_loss_many_saves(void) { power_loss_sweep(7); }

int main(int argc, char **argv)
{
    if (UnityParseOptions(argc, argv) != 0) {
        return 1;
    }
    UNITY_BEGIN();
    RUN_TEST(test_crc32_check_value);
    RUN_TEST(test_blank_is_missing_and_garbage_is_corrupt);
    RUN_TEST(test_layout_as_documented);
    RUN_TEST(test_saves_alternate_and_carry_the_others);
    RUN_TEST(test_removed_record_does_not_come_back);
    RUN_TEST(test_bad_payload_in_newest_falls_back_per_record);
    RUN_TEST(test_a_record_only_intact_in_the_half_being_erased_survives);
    RUN_TEST(test_other_version_is_reported_not_used);
    RUN_TEST(test_every_bit_flip_of_the_newest_copy);
    RUN_TEST(test_storage_errors);
    RUN_TEST(test_sequence_wraps);
    RUN_TEST(test_power_loss_first_save);
    RUN_TEST(test_power_loss_one_record);
    RUN_TEST(test_power_loss_three_records);
    RUN_TEST(test_power_loss_many_saves);
    return UNITY_END();
}
