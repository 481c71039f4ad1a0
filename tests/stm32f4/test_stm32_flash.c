/*
 * Flash NVM driver (firmware/board/stm32f4/stm32f4_flash.c) against the
 * flash interface model (model_flash.c): unlock keys, lock afterwards,
 * sector erase of whole sectors only, bounded busy waits, word and byte
 * programming with the matching PSIZE, every error flag -> HAL_ERR_IO, the
 * data cache reset after an erase; and, through the firmware, a failed save
 * answers NVM_ERROR and leaves the previous record in place.
 */
#include <stddef.h>
#include <string.h>

#include "hal_mock.h"
#include "hd_can_proto.h"
#include "hd_fw.h"
#include "model_flash.h"
#include "stm32f4_flash.h"
#include "unity.h"

#define SECTOR FLASH_MODEL_SECTOR_BYTES
#define ERASE_POLLS 4096u
#define PROGRAM_POLLS 64u

static flash_model_t g_model;
static stm32_flash_drv_t g_drv;

void setUp(void)
{
    reg_model_reset();
    flash_model_init(&g_model);
    stm32_flash_config_t c = {.regs = &g_model.regs, .mem = g_model.mem,
                              .first_sector = FLASH_MODEL_FIRST_SNB,
                              .sector_count = FLASH_MODEL_SECTORS, .sector_bytes = SECTOR,
                              .erase_polls = ERASE_POLLS, .program_polls = PROGRAM_POLLS};
    stm32_flash_init(&g_drv, &c);
}

void tearDown(void)
{
}

static int all_bytes(const uint8_t *p, size_t n, uint8_t v)
{
    for (size_t i = 0; i < n; i++) {
        if (p[i] != v) {
            return 0;
        }
    }
    return 1;
}

static void assert_locked_and_clean(void)
{
    TEST_ASSERT_TRUE(g_model.regs.CR & STM32_FLASH_CR_LOCK);
    TEST_ASSERT_EQUAL_HEX32(0u, g_model.regs.SR & STM32_FLASH_SR_ERRORS);
    TEST_ASSERT_FALSE(g_model.locked_until_reset);
    TEST_ASSERT_EQUAL_UINT(0u, g_model.violations);
    TEST_ASSERT_EQUAL_UINT(0u, reg_model_stray_accesses());
}

static void test_register_offsets_match_rm0090(void)
{
    TEST_ASSERT_EQUAL_UINT(0x00u, offsetof(stm32_flash_t, ACR));
    TEST_ASSERT_EQUAL_UINT(0x04u, offsetof(stm32_flash_t, KEYR));
    TEST_ASSERT_EQUAL_UINT(0x0Cu, offsetof(stm32_flash_t, SR));
    TEST_ASSERT_EQUAL_UINT(0x10u, offsetof(stm32_flash_t, CR));
    TEST_ASSERT_EQUAL_UINT(0x14u, offsetof(stm32_flash_t, OPTCR));
}

static void test_erase_one_half_leaves_the_other(void)
{
    flash_model_fill(&g_model, 0u, 0x00u);
    flash_model_fill(&g_model, 1u, 0x5Au);
    hal_nvm_t nvm;
    stm32_flash_bind(&g_drv, &nvm);
    TEST_ASSERT_EQUAL_UINT(2u * SECTOR, nvm.size);
    TEST_ASSERT_EQUAL_INT(HAL_OK, nvm.erase(nvm.ctx, 0u, SECTOR));
    TEST_ASSERT_TRUE(all_bytes(g_model.mem, SECTOR, 0xFFu));
    TEST_ASSERT_TRUE(all_bytes(g_model.mem + SECTOR, SECTOR, 0x5Au));
    TEST_ASSERT_EQUAL_UINT(1u, g_model.erases);
    assert_locked_and_clean();

    TEST_ASSERT_EQUAL_INT(HAL_OK, nvm.erase(nvm.ctx, SECTOR, SECTOR)); /* copy B: SNB 2 */
    TEST_ASSERT_TRUE(all_bytes(g_model.mem + SECTOR, SECTOR, 0xFFu));
    flash_model_fill(&g_model, 0u, 0x00u);
    flash_model_fill(&g_model, 1u, 0x00u);
    TEST_ASSERT_EQUAL_INT(HAL_OK, nvm.erase(nvm.ctx, 0u, 2u * SECTOR));
    TEST_ASSERT_TRUE(all_bytes(g_model.mem, 2u * SECTOR, 0xFFu));
    TEST_ASSERT_EQUAL_UINT(4u, g_model.erases);
    assert_locked_and_clean();
}

static void test_erase_refuses_partial_sectors(void)
{
    TEST_ASSERT_EQUAL_INT(HAL_ERR_RANGE, stm32_flash_erase(&g_drv, 0u, 100u));
    TEST_ASSERT_EQUAL_INT(HAL_ERR_RANGE, stm32_flash_erase(&g_drv, 100u, SECTOR));
    TEST_ASSERT_EQUAL_INT(HAL_ERR_RANGE, stm32_flash_erase(&g_drv, SECTOR, 2u * SECTOR));
    TEST_ASSERT_EQUAL_INT(HAL_ERR_RANGE, stm32_flash_erase(&g_drv, 0u, 0u));
    TEST_ASSERT_EQUAL_UINT(0u, g_model.erases);
    TEST_ASSERT_EQUAL_UINT(0u, g_model.rm.writes); /* refused before unlocking */
}

static void test_busy_that_never_ends_is_an_error_within_the_bound(void)
{
    g_model.busy_forever = true;
    g_model.regs.SR = 0u;
    TEST_ASSERT_EQUAL_INT(HAL_ERR_IO, stm32_flash_erase(&g_drv, 0u, SECTOR));
    TEST_ASSERT_LESS_OR_EQUAL(ERASE_POLLS + PROGRAM_POLLS + 16u, g_model.rm.reads);
    TEST_ASSERT_EQUAL_UINT(1u, g_drv.errors);
    TEST_ASSERT_TRUE(g_model.regs.CR & STM32_FLASH_CR_LOCK);
}

static void test_program_words_and_bytes(void)
{
    const uint8_t data[11] = {1, 2, 3, 4, 5, 6, 7, 8, 9, 10, 11};
    TEST_ASSERT_EQUAL_INT(HAL_OK, stm32_flash_write(&g_drv, 1u, data, sizeof data));
    TEST_ASSERT_EQUAL_MEMORY(data, g_model.mem + 1, sizeof data);
    TEST_ASSERT_EQUAL_UINT8(0xFFu, g_model.mem[0]);
    TEST_ASSERT_EQUAL_UINT8(0xFFu, g_model.mem[12]);
    /* bytes at 1, 2, 3 (PSIZE x8), words at 4 and 8 (PSIZE x32) */
    TEST_ASSERT_EQUAL_UINT(5u, g_model.programs);
    uint8_t back[11];
    TEST_ASSERT_EQUAL_INT(HAL_OK, stm32_flash_read(&g_drv, 1u, back, sizeof back));
    TEST_ASSERT_EQUAL_MEMORY(data, back, sizeof data);
    assert_locked_and_clean();
    TEST_ASSERT_EQUAL_INT(HAL_ERR_RANGE, stm32_flash_write(&g_drv, 2u * SECTOR - 2u, data, 3u));
    TEST_ASSERT_EQUAL_INT(HAL_ERR_RANGE, stm32_flash_read(&g_drv, 2u * SECTOR, back, 1u));
}

static void test_every_error_flag_is_an_io_error(void)
{
    const uint32_t flags[] = {STM32_FLASH_SR_PGSERR, STM32_FLASH_SR_PGPERR,
                              STM32_FLASH_SR_PGAERR, STM32_FLASH_SR_WRPERR,
                              STM32_FLASH_SR_OPERR};
    const uint8_t data[8] = {0};
    for (size_t i = 0; i < sizeof flags / sizeof flags[0]; i++) {
        setUp();
        g_model.inject_program_error = flags[i];
        TEST_ASSERT_EQUAL_INT(HAL_ERR_IO, stm32_flash_write(&g_drv, 0u, data, sizeof data));
        TEST_ASSERT_EQUAL_HEX32(flags[i], g_drv.last_sr);
        TEST_ASSERT_EQUAL_UINT(1u, g_drv.errors);
        assert_locked_and_clean(); /* flags cleared, locked again */
        setUp();
        g_model.inject_erase_error = flags[i];
        TEST_ASSERT_EQUAL_INT(HAL_ERR_IO, stm32_flash_erase(&g_drv, SECTOR, SECTOR));
        assert_locked_and_clean();
    }
    /* A flag is an error even where the memory happens to hold the data
     * (0xFF over erased flash: the read-back alone would pass). */
    setUp();
    const uint8_t ones[4] = {0xFFu, 0xFFu, 0xFFu, 0xFFu};
    g_model.inject_program_error = STM32_FLASH_SR_PGPERR;
    TEST_ASSERT_EQUAL_INT(HAL_ERR_IO, stm32_flash_write(&g_drv, 8u, ones, sizeof ones));
    setUp();
    g_model.wrp_sectors = 2u; /* copy B write protected */
    TEST_ASSERT_EQUAL_INT(HAL_ERR_IO, stm32_flash_erase(&g_drv, SECTOR, SECTOR));
    TEST_ASSERT_EQUAL_INT(HAL_ERR_IO, stm32_flash_write(&g_drv, SECTOR, data, 4u));
    TEST_ASSERT_EQUAL_HEX32(STM32_FLASH_SR_WRPERR, g_drv.last_sr);
    TEST_ASSERT_EQUAL_INT(HAL_OK, stm32_flash_write(&g_drv, 0u, data, 4u));
}

static void test_write_over_unerased_data_is_caught(void)
{
    flash_model_fill(&g_model, 0u, 0x0Fu);
    const uint8_t data[4] = {0xF0u, 0xF0u, 0xF0u, 0xF0u};
    TEST_ASSERT_EQUAL_INT(HAL_ERR_IO, stm32_flash_write(&g_drv, 0u, data, sizeof data));
    TEST_ASSERT_EQUAL_UINT(0u, g_drv.last_sr); /* no flag: the read-back caught it */
}

static void test_bad_key_state_is_an_io_error(void)
{
    g_model.locked_until_reset = true; /* after a wrong key sequence */
    const uint8_t data[4] = {0};
    TEST_ASSERT_EQUAL_INT(HAL_ERR_IO, stm32_flash_write(&g_drv, 0u, data, sizeof data));
    TEST_ASSERT_EQUAL_UINT(0u, g_model.programs);
    TEST_ASSERT_TRUE(all_bytes(g_model.mem, 8u, 0xFFu));
}

static void test_data_cache_is_reset_after_an_erase(void)
{
    g_model.regs.ACR = 5u | STM32_FLASH_ACR_ICEN | STM32_FLASH_ACR_DCEN;
    TEST_ASSERT_EQUAL_INT(HAL_OK, stm32_flash_erase(&g_drv, 0u, SECTOR));
    TEST_ASSERT_EQUAL_UINT(1u, g_model.dcache_resets);
    TEST_ASSERT_EQUAL_HEX32(5u | STM32_FLASH_ACR_ICEN | STM32_FLASH_ACR_DCEN, g_model.regs.ACR);
    TEST_ASSERT_EQUAL_UINT(0u, g_model.violations);
}

/* ------------------------------------------------- through the firmware */

static hal_mock_t g_mock;
static hal_t g_hal;
static hd_fw_t g_fw;

static void firmware_on_flash(void)
{
    hal_mock_init(&g_mock);
    hal_mock_bind(&g_mock, &g_hal);
    stm32_flash_bind(&g_drv, &g_hal.nvm);
    hd_fw_config_t cfg;
    hd_fw_config_default(&cfg);
    TEST_ASSERT_EQUAL_INT(HD_FW_OK, hd_fw_init(&g_fw, &g_hal, &cfg));
}

/* Sends a command to node 1 and runs tick + background until its ACK. */
static hd_can_ack_t command(const hd_can_cmd_t *c)
{
    hal_can_frame_t f;
    hd_can_encode_cmd(1u, c, &f);
    TEST_ASSERT_EQUAL_INT(0, hal_mock_push_rx(&g_mock, &f));
    uint32_t seen = hal_mock_tx_count(&g_mock);
    for (int round = 0; round < 20; round++) {
        (void)hal_mock_push(&g_mock, 0, 0u);
        hd_fw_isr(&g_fw);
        (void)hd_fw_background(&g_fw);
        for (; seen < hal_mock_tx_count(&g_mock); seen++) {
            hd_can_ack_t a;
            if (hd_can_decode_ack(hal_mock_tx(&g_mock, seen), &a) == 0 &&
                a.opcode == c->opcode && a.token == c->token) {
                return a;
            }
        }
    }
    TEST_FAIL_MESSAGE("no ACK");
    hd_can_ack_t none = {0};
    return none;
}

static hd_can_ack_t set_gain(float gain, uint8_t token)
{
    hd_can_cmd_t c = {0};
    c.opcode = HD_CMD_SET_PARAM;
    c.token = token;
    c.arg.set_param.id = HD_PARAM_CALIB_GAIN_NM_PER_V;
    c.arg.set_param.value = gain;
    return command(&c);
}

static hd_can_ack_t save(uint8_t token)
{
    hd_can_cmd_t c = {0};
    c.opcode = HD_CMD_CALIB_SAVE;
    c.token = token;
    c.arg.calib_save.calibrated_unix_s = 1700000000u;
    return command(&c);
}

static float saved_gain_after_reboot(void)
{
    firmware_on_flash(); /* boots from the flash contents */
    hd_can_cmd_t c = {0};
    c.opcode = HD_CMD_GET_PARAM;
    c.token = 77u;
    c.arg.get_param.id = HD_PARAM_CALIB_GAIN_NM_PER_V;
    hd_can_ack_t a = command(&c);
    TEST_ASSERT_EQUAL_UINT8(HD_CAN_RES_OK, a.result);
    return a.value;
}

static void test_failed_save_answers_nvm_error_and_keeps_the_old_record(void)
{
    const uint32_t faults[] = {0u, 1u}; /* erase error, then program error */
    for (size_t k = 0; k < 2u; k++) {
        setUp();
        firmware_on_flash();
        TEST_ASSERT_EQUAL_UINT8(HD_CAN_RES_OK, set_gain(6.5f, 1u).result);
        TEST_ASSERT_EQUAL_UINT8(HD_CAN_RES_OK, save(2u).result);
        uint8_t before[2u * SECTOR];
        memcpy(before, g_model.mem, sizeof before);
        TEST_ASSERT_EQUAL_UINT8(HD_CAN_RES_OK, set_gain(9.0f, 3u).result);
        if (faults[k] == 0u) {
            g_model.inject_erase_error = STM32_FLASH_SR_OPERR;
        } else {
            g_model.inject_program_error = STM32_FLASH_SR_PGPERR;
        }
        TEST_ASSERT_EQUAL_UINT8(HD_CAN_RES_NVM_ERROR, save(4u).result);
        TEST_ASSERT_GREATER_OR_EQUAL(1u, g_drv.errors);
        /* The first save went into one half of the blank store; that copy
         * (the 6.5 record) is untouched by the failed save. */
        int a_blank = all_bytes(before, SECTOR, 0xFFu);
        int b_blank = all_bytes(before + SECTOR, SECTOR, 0xFFu);
        TEST_ASSERT_TRUE(a_blank != b_blank);
        size_t old = a_blank ? SECTOR : 0u;
        TEST_ASSERT_EQUAL_MEMORY(before + old, g_model.mem + old, SECTOR);
        TEST_ASSERT_EQUAL_FLOAT(6.5f, saved_gain_after_reboot());
        TEST_ASSERT_EQUAL_UINT(0u, g_model.violations);
    }
}

static void test_saves_alternate_halves_and_survive_a_reboot(void)
{
    firmware_on_flash();
    static uint8_t before[2u * SECTOR];
    size_t last = 2u; /* the half the previous save wrote (none yet) */
    for (int i = 0; i < 4; i++) {
        TEST_ASSERT_EQUAL_UINT8(HD_CAN_RES_OK, set_gain(2.0f + (float)i, 10u).result);
        memcpy(before, g_model.mem, sizeof before);
        TEST_ASSERT_EQUAL_UINT8(HD_CAN_RES_OK, save(11u).result);
        /* Exactly one half was rewritten, the one the previous save left. */
        int a_same = memcmp(before, g_model.mem, SECTOR) == 0;
        int b_same = memcmp(before + SECTOR, g_model.mem + SECTOR, SECTOR) == 0;
        TEST_ASSERT_TRUE(a_same != b_same);
        size_t half = a_same ? 1u : 0u;
        TEST_ASSERT_TRUE(half != last);
        last = half;
    }
    TEST_ASSERT_GREATER_OR_EQUAL(4u, g_model.erases);
    TEST_ASSERT_EQUAL_FLOAT(5.0f, saved_gain_after_reboot());
    TEST_ASSERT_EQUAL_UINT(0u, g_model.violations);
}

int main(int argc, char **argv)
{
    if (UnityParseOptions(argc, argv) != 0) {
        return 1;
    }
    UNITY_BEGIN();
    RUN_TEST(test_register_offsets_match_rm0090);
    RUN_TEST(test_erase_one_half_leaves_the_other);
    RUN_TEST(test_erase_refuses_partial_sectors);
    RUN_TEST(test_busy_that_never_ends_is_an_error_within_the_bound);
    RUN_TEST(test_program_words_and_bytes);
    RUN_TEST(test_every_error_flag_is_an_io_error);
    RUN_TEST(test_write_over_unerased_data_is_caught);
    RUN_TEST(test_bad_key_state_is_an_io_error);
    RUN_TEST(test_data_cache_is_reset_after_an_erase);
    RUN_TEST(test_failed_save_answers_nvm_error_and_keeps_the_old_record);
    RUN_TEST(test_saves_alternate_halves_and_survive_a_reboot);
    return UNITY_END();
}
