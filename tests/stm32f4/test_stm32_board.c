/*
 * The whole board on the register models: stm32_board_boot (clock, watchdog,
 * pins, tick timer, ADC, encoders, CAN, flash NVM) as the ODrive image runs
 * it, then the firmware on top (hd_fw_init, ticks from the modelled timer
 * whose TRGO starts the modelled ADC), checked on the modelled CAN bus:
 * the boot frame reports a watchdog reset, a HardFault record left in RAM
 * and a clock that fell back; telemetry carries the ADC samples; the
 * firmware's receive filter is in the CAN controller.  Also: the pin
 * tables in docs/how-to/stm32f4.md are the ones the board definitions produce
 * (run with --print-pins to print them).
 */
#include <stdio.h>
#include <stdlib.h>
#include <string.h>

#include "hd_can_proto.h"
#include "hd_fw.h"
#include "model_can.h"
#include "model_flash.h"
#include "model_misc.h"
#include "stm32f4_board.h"
#include "hd_fw_internal.h"
#include "unity.h"

/* The markers are assembly on the target; no-ops here. */
void hd_mark_begin(void);
void hd_mark_end(void);
void hd_mark_begin(void)
{
}
void hd_mark_end(void)
{
}

static rcc_model_t g_rcc;
static flash_model_t g_flash;
static iwdg_model_t g_iwdg;
static stm32_gpio_t g_gpio_regs[STM32_GPIO_PORTS];
static ram_model_t g_gpio;
static tim_model_t g_tick, g_enc_m, g_enc_o;
static adc_model_t g_adc;
static stm32_adc_common_t g_adc_common_regs;
static ram_model_t g_adc_common;
static can_model_t g_can;
static stm32_board_t g_board;
static stm32_fault_record_t g_noinit;
static hd_fw_t g_fw;
static hal_t g_hal;

void setUp(void)
{
    reg_model_reset();
    flash_model_init(&g_flash);
    rcc_model_init(&g_rcc, &g_flash.regs, 8000000u);
    iwdg_model_init(&g_iwdg);
    memset(g_gpio_regs, 0, sizeof g_gpio_regs);
    ram_model_init(&g_gpio, "GPIO", g_gpio_regs, sizeof g_gpio_regs);
    tim_model_init(&g_tick, "TIM1");
    tim_model_init(&g_enc_m, "TIM3");
    tim_model_init(&g_enc_o, "TIM4");
    adc_model_init(&g_adc);
    memset(&g_adc_common_regs, 0, sizeof g_adc_common_regs);
    ram_model_init(&g_adc_common, "ADC common", &g_adc_common_regs, sizeof g_adc_common_regs);
    can_model_init(&g_can);
    g_tick.trgo = adc_model_trigger;
    g_tick.trgo_ctx = &g_adc;
    g_tick.trgo_source = STM32_ADC_JEXTSEL_TIM1_TRGO;
    memset(&g_noinit, 0x5A, sizeof g_noinit); /* RAM garbage: not a record */
}

void tearDown(void)
{
}

static void boot(void)
{
    stm32_periph_t p;
    memset(&p, 0, sizeof p);
    p.rcc = &g_rcc.regs;
    p.flash = &g_flash.regs;
    p.iwdg = &g_iwdg.regs;
    for (uint32_t i = 0; i < STM32_GPIO_PORTS; i++) {
        p.gpio[i] = &g_gpio_regs[i];
    }
    p.tick = &g_tick.regs;
    p.adc = &g_adc.regs;
    p.adc_common = &g_adc_common_regs;
    p.motor_enc = &g_enc_m.regs;
    p.output_enc = &g_enc_o.regs;
    p.can = &g_can.regs;
    p.nvm_mem = g_flash.mem;
    (void)stm32_board_boot(&g_board, &stm32_board_odrive_v3, &p, &g_noinit, &g_hal);
    hd_fw_config_t cfg;
    hd_fw_config_default(&cfg);
    TEST_ASSERT_EQUAL_INT(HD_FW_OK, hd_fw_init(&g_fw, &g_hal, &cfg));
    stm32_board_start(&g_board);
}

/* One millisecond of the modelled timer, then the tick interrupt and the
 * bus carrying what the mailboxes hold. */
static void tick(void)
{
    tim_model_clock(&g_tick, g_board.clock.tim_apb2_hz / 1000u);
    stm32_board_tick(&g_board, &g_fw);
    (void)hd_fw_background(&g_fw);
    for (int i = 0; i < 6; i++) {
        (void)can_model_bus_step(&g_can);
        stm32_can_tx_service(&g_board.can);
    }
}

static int find_boot(hd_can_boot_t *out)
{
    for (size_t i = 0; i < g_can.wire_count; i++) {
        if (hd_can_decode_boot(&g_can.wire[i], out) == 0) {
            return 1;
        }
    }
    return 0;
}

static void test_boot_brings_every_part_up(void)
{
    g_rcc.regs.CSR = STM32_RCC_CSR_PORRSTF | STM32_RCC_CSR_BORRSTF | STM32_RCC_CSR_PINRSTF;
    boot();
    TEST_ASSERT_EQUAL_HEX32(0u, g_board.init_errors);
    TEST_ASSERT_EQUAL_UINT(168000000u, rcc_model_sysclk(&g_rcc));
    TEST_ASSERT_TRUE(g_iwdg.started);
    TEST_ASSERT_EQUAL_UINT(STM32_BOARD_IWDG_RELOAD, g_iwdg.regs.RLR);
    TEST_ASSERT_EQUAL_INT(CAN_MODE_NORMAL, g_can.mode);
    TEST_ASSERT_EQUAL_UINT(0u, g_can.violations + g_rcc.violations + g_flash.violations);
    TEST_ASSERT_EQUAL_UINT(0u, reg_model_stray_accesses());
    /* The firmware asked for its command and feed-forward ids of node 1. */
    hal_can_frame_t cmd = {0};
    cmd.id = hd_can_id(HD_CAN_FRAME_CMD, 1u);
    cmd.flags = HAL_CAN_FLAG_EXT;
    cmd.len = 8u;
    TEST_ASSERT_TRUE(can_model_deliver(&g_can, &cmd));
    cmd.id = hd_can_id(HD_CAN_FRAME_CMD, 2u);
    TEST_ASSERT_FALSE(can_model_deliver(&g_can, &cmd));

    g_adc.input[3] = 2048u + 300u; /* ODrive GPIO4 = ADC1 channel 3 */
    for (int k = 0; k < 50; k++) {
        tim_model_encoder_move(&g_enc_m, 107);
        tick();
    }
    TEST_ASSERT_EQUAL_UINT(50u, g_board.ticks);
    TEST_ASSERT_EQUAL_INT32(300, hd_fw_last_sample(&g_fw)->bridge_counts);
    TEST_ASSERT_GREATER_OR_EQUAL(50u, g_adc.conversions);
    TEST_ASSERT_EQUAL_UINT(0u, g_board.adc.timeouts);
    hd_can_boot_t b;
    TEST_ASSERT_TRUE(find_boot(&b));
    TEST_ASSERT_EQUAL_HEX8(HAL_RESET_POWER_ON, b.reset_cause);
    TEST_ASSERT_FALSE(b.fault_valid);
    hal_counters_t c;
    stm32_can_counters(&g_board.can, &c);
    TEST_ASSERT_GREATER_OR_EQUAL(100u, c.can_tx_ok); /* telemetry went out */
}

/* A driver that cannot start is not silent: the board records it and the
 * firmware's INFO item BOARD_INIT_ERRORS reports it (here a bus held
 * dominant, so bxCAN never reaches normal mode). */
static void test_failed_driver_is_reported_by_info(void)
{
    g_can.bus_dominant = true;
    boot();
    TEST_ASSERT_EQUAL_HEX32(STM32_BOARD_INIT_CAN, g_board.init_errors);
    uint32_t v = 0u;
    TEST_ASSERT_TRUE(hd_fw_info_item(&g_fw, HD_INFO_BOARD_INIT_ERRORS, &v));
    TEST_ASSERT_EQUAL_HEX32(STM32_BOARD_INIT_CAN, v);
}

static void test_watchdog_reset_and_hardfault_are_reported_once(void)
{
    g_rcc.regs.CSR = STM32_RCC_CSR_IWDGRSTF | STM32_RCC_CSR_PINRSTF;
    const uint32_t frame[8] = {0, 0, 0, 0, 0, 0x08012345u, 0x0800ABCDu, 0x01000000u};
    stm32_fault_record_save(&g_noinit, frame, STM32_SCB_CFSR_BFARVALID | 0x200u, 0x40000000u,
                            0u, 0x20030000u);
    boot();
    tick();
    hd_can_boot_t b;
    TEST_ASSERT_TRUE(find_boot(&b));
    TEST_ASSERT_EQUAL_HEX8(HAL_RESET_WATCHDOG, b.reset_cause);
    TEST_ASSERT_TRUE(b.fault_valid);
    TEST_ASSERT_EQUAL_HEX32(0x0800ABCDu, b.fault_pc);
    hal_boot_info_t info;
    g_hal.system.boot_info(g_hal.system.ctx, &info); /* already read by the firmware */
    TEST_ASSERT_FALSE(info.fault_valid);

    stm32_fault_record_t ram = g_noinit; /* .noinit survives the next reset */
    setUp();
    g_noinit = ram; /* the record was taken from it: the next boot has none */
    g_rcc.regs.CSR = STM32_RCC_CSR_SFTRSTF | STM32_RCC_CSR_PINRSTF;
    boot();
    tick();
    TEST_ASSERT_TRUE(find_boot(&b));
    TEST_ASSERT_EQUAL_HEX8(HAL_RESET_SOFTWARE, b.reset_cause);
    TEST_ASSERT_FALSE(b.fault_valid);
}

static void test_clock_fallback_is_reported_and_timing_follows(void)
{
    g_rcc.hse_present = false;
    boot();
    TEST_ASSERT_EQUAL_UINT(16000000u, g_board.clock.sysclk_hz);
    /* CAN bit timing and the tick come from the clocks really in effect. */
    stm32_can_timing_t t;
    TEST_ASSERT_TRUE(stm32_can_timing(16000000u, 1000000u, &t));
    TEST_ASSERT_EQUAL_HEX32(stm32_can_btr(&t), g_can.regs.BTR);
    /* By hand: 16 MHz / 1 Mbit/s = 16 quanta at prescaler 1, BS1 13 + BS2 2,
     * sample point 14/16 = 87.5 %: BTR TS2 = 1, TS1 = 12, BRP = 0. */
    TEST_ASSERT_EQUAL_HEX32(0x001C0000u, g_can.regs.BTR);
    for (int k = 0; k < 3; k++) {
        tick();
    }
    TEST_ASSERT_EQUAL_UINT(3u, g_board.ticks);
    hd_can_boot_t b;
    TEST_ASSERT_TRUE(find_boot(&b));
    TEST_ASSERT_TRUE(b.reset_cause & HAL_RESET_CLOCK);
}

static void test_missing_conversion_is_an_adc_fault(void)
{
    boot();
    tick();
    g_adc.never_completes = true;
    g_adc.converting = false;
    tick();
    TEST_ASSERT_EQUAL_UINT(1u, g_board.adc.timeouts);
    TEST_ASSERT_TRUE(hd_fw_last_sample(&g_fw)->faults & HD_FAULT_ADC_ERROR);
    TEST_ASSERT_FALSE(hd_fw_last_sample(&g_fw)->valid);
}

/* ------------------------------------------------------ pin tables */

typedef struct {
    char text[4096];
    size_t len;
} buf_t;

static void put(void *ctx, const char *s)
{
    buf_t *b = ctx;
    size_t n = strlen(s);
    if (b->len + n < sizeof b->text) {
        memcpy(b->text + b->len, s, n + 1u);
        b->len += n;
    }
}

static const stm32_board_def_t *const BOARDS[] = {&stm32_board_odrive_v3,
                                                   &stm32_board_mini_cheetah};

static void test_docs_show_the_pin_tables_of_the_code(void)
{
    FILE *f = fopen(HD_SOURCE_DIR "/docs/how-to/stm32f4.md", "rb");
    TEST_ASSERT_NOT_NULL_MESSAGE(f, "docs/how-to/stm32f4.md");
    static char doc[131072];
    size_t n = fread(doc, 1, sizeof doc - 1u, f);
    fclose(f);
    doc[n] = '\0';
    for (size_t i = 0; i < sizeof BOARDS / sizeof BOARDS[0]; i++) {
        buf_t b = {{0}, 0};
        stm32_board_pin_table(BOARDS[i], put, &b);
        TEST_ASSERT_NOT_NULL_MESSAGE(strstr(doc, b.text),
                                     "a pin table differs from stm32f4_boards.c "
                                     "(stm32f4_board --print-pins prints them)");
    }
    /* The NVM the linker script reserves is what the definitions use. */
    TEST_ASSERT_EQUAL_UINT(1u, stm32_board_odrive_v3.nvm_first_sector);
    TEST_ASSERT_EQUAL_UINT(2u * 16384u, stm32_board_odrive_v3.nvm_sectors *
                                            stm32_board_odrive_v3.nvm_sector_bytes);
}

/* The microsecond clock against a 64-bit cycle total kept here: over
 * steps up to 25 s at 168 MHz, with the 32-bit counter wrapping many
 * times, time is floor(total cycles / 168) at every call. */
static void test_cycle_clock_is_floor_of_total_cycles(void)
{
    stm32_cycle_clock_t c = {.last = 0xFFFFF000u, .rem_cycles = 0u, .us = 0u,
                             .cycles_per_us = 168u};
    uint64_t total = 0u;
    uint32_t counter = c.last, seed = 12345u;
    for (int i = 0; i < 2000; i++) {
        seed = seed * 1664525u + 1013904223u;
        /* mostly one tick, sometimes a long gap, sometimes the longest */
        uint32_t step = (i % 97 == 0) ? 4200000000u
                                      : (i % 13 == 0 ? seed % 4200000000u : 168000u + (seed >> 20));
        counter += step;
        total += step;
        TEST_ASSERT_EQUAL_UINT64(total / 168u, stm32_cycle_clock_advance(&c, counter));
    }
    TEST_ASSERT_TRUE(total > 40ull * 0xFFFFFFFFull); /* wrapped many times */
}

static void print_pins(void)
{
    for (size_t i = 0; i < sizeof BOARDS / sizeof BOARDS[0]; i++) {
        buf_t b = {{0}, 0};
        stm32_board_pin_table(BOARDS[i], put, &b);
        printf("%s (%s):\n\n%s\n", BOARDS[i]->name, BOARDS[i]->mcu, b.text);
    }
}

int main(int argc, char **argv)
{
    if (argc == 2 && strcmp(argv[1], "--print-pins") == 0) {
        print_pins();
        return 0;
    }
    if (UnityParseOptions(argc, argv) != 0) {
        return 1;
    }
    UNITY_BEGIN();
    RUN_TEST(test_boot_brings_every_part_up);
    RUN_TEST(test_failed_driver_is_reported_by_info);
    RUN_TEST(test_watchdog_reset_and_hardfault_are_reported_once);
    RUN_TEST(test_clock_fallback_is_reported_and_timing_follows);
    RUN_TEST(test_missing_conversion_is_an_adc_fault);
    RUN_TEST(test_docs_show_the_pin_tables_of_the_code);
    RUN_TEST(test_cycle_clock_is_floor_of_total_cycles);
    return UNITY_END();
}
