/*
 * Timer and ADC drivers (stm32f4_tim.c, stm32f4_adc.c) against the timer
 * and ADC models: the tick period from the kernel clock (exactly 1000
 * update events per simulated second on TIM1 at 168 MHz, TIM2 at 84 MHz and
 * QEMU's 1 GHz), TRGO starting the injected conversion of the bridge
 * channel, the read with its bounded wait, saturation and sign, and the
 * encoder count across 16-bit counter wraps.
 */
#include <stddef.h>
#include <stdint.h>
#include <string.h>

#include "model_misc.h"
#include "stm32f4_adc.h"
#include "stm32f4_tim.h"
#include "unity.h"

#define POLLS 200u

static tim_model_t g_tim;
static adc_model_t g_adc;
static stm32_adc_common_t g_common_regs;
static ram_model_t g_common;
static stm32_adc_drv_t g_drv;

void setUp(void)
{
    reg_model_reset();
    tim_model_init(&g_tim, "TIM1");
    adc_model_init(&g_adc);
    memset(&g_common_regs, 0, sizeof g_common_regs);
    ram_model_init(&g_common, "ADC common", &g_common_regs, sizeof g_common_regs);
    g_tim.trgo = adc_model_trigger;
    g_tim.trgo_ctx = &g_adc;
    g_tim.trgo_source = STM32_ADC_JEXTSEL_TIM1_TRGO;
}

void tearDown(void)
{
}

static void test_register_offsets_match_rm0090(void)
{
    TEST_ASSERT_EQUAL_UINT(0x08u, offsetof(stm32_tim_t, SMCR));
    TEST_ASSERT_EQUAL_UINT(0x10u, offsetof(stm32_tim_t, SR));
    TEST_ASSERT_EQUAL_UINT(0x24u, offsetof(stm32_tim_t, CNT));
    TEST_ASSERT_EQUAL_UINT(0x2Cu, offsetof(stm32_tim_t, ARR));
    TEST_ASSERT_EQUAL_UINT(0x44u, offsetof(stm32_tim_t, BDTR));
    TEST_ASSERT_EQUAL_UINT(0x14u, offsetof(stm32_adc_t, JOFR[0]));
    TEST_ASSERT_EQUAL_UINT(0x38u, offsetof(stm32_adc_t, JSQR));
    TEST_ASSERT_EQUAL_UINT(0x3Cu, offsetof(stm32_adc_t, JDR[0]));
    TEST_ASSERT_EQUAL_UINT(0x4Cu, offsetof(stm32_adc_t, DR));
    TEST_ASSERT_EQUAL_UINT(0x04u, offsetof(stm32_adc_common_t, CCR));
}

static void test_period_is_exact_and_fits(void)
{
    /* 170 MHz (an STM32G4): the first prescaler that fits (3) does not
     * divide 170000, the next (4) does. */
    const uint32_t clocks[] = {168000000u, 84000000u, 16000000u, 1000000000u, 180000000u,
                               170000000u};
    for (size_t i = 0; i < sizeof clocks / sizeof clocks[0]; i++) {
        stm32_tim_period_t p;
        TEST_ASSERT_TRUE(stm32_tim_period(clocks[i], 1000u, 0xFFFFu, &p));
        TEST_ASSERT_EQUAL_UINT64(clocks[i] / 1000u, (uint64_t)(p.psc + 1u) * (p.arr + 1u));
        TEST_ASSERT_LESS_OR_EQUAL(0xFFFFu, p.arr);
        TEST_ASSERT_LESS_OR_EQUAL(0xFFFFu, p.psc);
        /* finest resolution: one less prescale would not fit the counter */
        TEST_ASSERT_TRUE(p.psc == 0u || (clocks[i] / 1000u) / p.psc > 0x10000u ||
                         (clocks[i] / 1000u) % p.psc != 0u);
    }
    stm32_tim_period_t p;
    TEST_ASSERT_FALSE(stm32_tim_period(1000001u, 1000u, 0xFFFFu, &p)); /* not exact */
    TEST_ASSERT_FALSE(stm32_tim_period(168000000u, 0u, 0xFFFFu, &p));
}

/* One simulated second of the timer: the number of update interrupts. */
static uint32_t ticks_in_one_second(uint32_t clock_hz)
{
    uint32_t ticks = 0u;
    const uint32_t step = clock_hz / 10000u; /* 100 us of kernel clocks */
    for (uint32_t i = 0; i < 10000u; i++) {
        tim_model_clock(&g_tim, step);
        if (stm32_tick_ack(&g_tim.regs)) {
            ticks++;
        }
    }
    return ticks;
}

static void test_tick_runs_at_1khz_from_each_kernel_clock(void)
{
    const uint32_t clocks[] = {168000000u, 84000000u, 16000000u, 1000000000u};
    for (size_t i = 0; i < sizeof clocks / sizeof clocks[0]; i++) {
        setUp();
        TEST_ASSERT_EQUAL_INT(HAL_OK, stm32_tick_init(&g_tim.regs, clocks[i], 1000u, 0xFFFFu));
        TEST_ASSERT_FALSE(g_tim.regs.SR & STM32_TIM_SR_UIF); /* configuring is no tick */
        STM32_WR(g_tim.regs.EGR, STM32_TIM_EGR_UG); /* nor a later software update (URS) */
        TEST_ASSERT_FALSE(g_tim.regs.SR & STM32_TIM_SR_UIF);
        TEST_ASSERT_EQUAL_UINT(0u, ticks_in_one_second(clocks[i])); /* not started */
        stm32_tick_start(&g_tim.regs);
        TEST_ASSERT_EQUAL_UINT(1000u, ticks_in_one_second(clocks[i]));
        TEST_ASSERT_TRUE(g_tim.regs.DIER & STM32_TIM_DIER_UIE);
        stm32_tick_stop(&g_tim.regs);
        TEST_ASSERT_EQUAL_UINT(0u, ticks_in_one_second(clocks[i]));
    }
    TEST_ASSERT_EQUAL_INT(HAL_ERR_RANGE, stm32_tick_init(&g_tim.regs, 1000001u, 1000u, 0xFFFFu));
}

/* A tick body that ran a whole period: the next update is pending and
 * taken once (the firmware's deadline check, on the board clock, flags the
 * late tick as DEADLINE_MISS). */
static void test_overrun_is_seen(void)
{
    TEST_ASSERT_EQUAL_INT(HAL_OK, stm32_tick_init(&g_tim.regs, 168000000u, 1000u, 0xFFFFu));
    stm32_tick_start(&g_tim.regs);
    tim_model_clock(&g_tim, 168000u);
    TEST_ASSERT_TRUE(stm32_tick_ack(&g_tim.regs));
    TEST_ASSERT_FALSE(stm32_tick_ack(&g_tim.regs));
    tim_model_clock(&g_tim, 168000u); /* the body took a whole period */
    TEST_ASSERT_TRUE(stm32_tick_ack(&g_tim.regs));
    TEST_ASSERT_FALSE(stm32_tick_ack(&g_tim.regs));
}

static stm32_adc_config_t adc_config(uint8_t channel)
{
    stm32_adc_config_t c = {.adc = &g_adc.regs, .common = &g_common_regs, .channel = channel,
                            .jextsel = STM32_ADC_JEXTSEL_TIM1_TRGO, .sample_code = 3u,
                            .adcpre = 1u, .midscale_counts = 2048u, .ready_polls = POLLS};
    return c;
}

static void test_timer_trigger_converts_the_bridge_channel(void)
{
    stm32_adc_config_t c = adc_config(3u); /* ODrive GPIO4 = PA3 = ADC123_IN3 */
    TEST_ASSERT_EQUAL_INT(HAL_OK, stm32_adc_init(&g_drv, &c));
    TEST_ASSERT_EQUAL_INT(HAL_OK, stm32_tick_init(&g_tim.regs, 168000000u, 1000u, 0xFFFFu));
    /* The software update at init may start one conversion (TRGO = update);
     * count from a clean state. */
    hal_adc_sample_t s;
    (void)stm32_adc_read(&g_drv, &s);
    uint32_t before = g_adc.conversions;
    stm32_tick_start(&g_tim.regs);
    const int32_t inputs[] = {2048, 3000, 100, 0, 4095, 2047};
    for (size_t i = 0; i < sizeof inputs / sizeof inputs[0]; i++) {
        g_adc.input[3] = (uint32_t)inputs[i];
        g_adc.input[0] = 1234u; /* another channel: must not be the one read */
        tim_model_clock(&g_tim, 168000u);
        TEST_ASSERT_TRUE(stm32_tick_ack(&g_tim.regs));
        TEST_ASSERT_EQUAL_INT(HAL_OK, stm32_adc_read(&g_drv, &s));
        TEST_ASSERT_EQUAL_INT32(inputs[i] - 2048, s.bridge_counts);
        TEST_ASSERT_EQUAL_INT(inputs[i] == 0 || inputs[i] == 4095, s.saturated);
    }
    TEST_ASSERT_EQUAL_UINT(before + 6u, g_adc.conversions);
    TEST_ASSERT_EQUAL_UINT(0u, g_drv.timeouts);
    /* Sample time 3 (56 cycles) for channel 3 in SMPR2, ADC clock PCLK2/4. */
    TEST_ASSERT_EQUAL_UINT(3u, (g_adc.regs.SMPR2 >> 9) & 7u);
    TEST_ASSERT_EQUAL_UINT(1u, (g_common_regs.CCR >> 16) & 3u);
    TEST_ASSERT_EQUAL_UINT(0u, reg_model_stray_accesses());

    setUp(); /* a channel in SMPR1 */
    c = adc_config(12u);
    TEST_ASSERT_EQUAL_INT(HAL_OK, stm32_adc_init(&g_drv, &c));
    TEST_ASSERT_EQUAL_UINT(3u, (g_adc.regs.SMPR1 >> 6) & 7u);
    g_adc.input[12] = 2100u;
    stm32_adc_start(&g_drv);
    TEST_ASSERT_EQUAL_INT(HAL_OK, stm32_adc_read(&g_drv, &s));
    TEST_ASSERT_EQUAL_INT32(52, s.bridge_counts);
}

static void test_a_conversion_that_never_completes_is_an_error(void)
{
    stm32_adc_config_t c = adc_config(3u);
    TEST_ASSERT_EQUAL_INT(HAL_OK, stm32_adc_init(&g_drv, &c));
    g_adc.never_completes = true;
    stm32_adc_start(&g_drv);
    uint32_t reads0 = g_adc.rm.reads;
    hal_adc_sample_t s;
    TEST_ASSERT_EQUAL_INT(HAL_ERR_IO, stm32_adc_read(&g_drv, &s));
    TEST_ASSERT_EQUAL_UINT(POLLS, g_adc.rm.reads - reads0);
    TEST_ASSERT_EQUAL_UINT(1u, g_drv.timeouts);

    setUp(); /* the trigger of another timer does not start it */
    TEST_ASSERT_EQUAL_INT(HAL_OK, stm32_adc_init(&g_drv, &c));
    g_tim.trgo_source = STM32_ADC_JEXTSEL_TIM2_TRGO;
    TEST_ASSERT_EQUAL_INT(HAL_OK, stm32_tick_init(&g_tim.regs, 84000000u, 1000u, 0xFFFFu));
    stm32_tick_start(&g_tim.regs);
    tim_model_clock(&g_tim, 84000u);
    TEST_ASSERT_EQUAL_INT(HAL_ERR_IO, stm32_adc_read(&g_drv, &s));
    TEST_ASSERT_GREATER_OR_EQUAL(1u, g_adc.triggers_ignored);

    stm32_adc_config_t bad = adc_config(16u);
    TEST_ASSERT_EQUAL_INT(HAL_ERR_RANGE, stm32_adc_init(&g_drv, &bad));
    bad = adc_config(3u);
    bad.sample_code = 8u;
    TEST_ASSERT_EQUAL_INT(HAL_ERR_RANGE, stm32_adc_init(&g_drv, &bad));
}

static void test_encoder_count_across_counter_wraps(void)
{
    tim_model_t enc_tim;
    tim_model_init(&enc_tim, "TIM3");
    stm32_encoder_t enc;
    stm32_encoder_config_t c = {.tim = &enc_tim.regs, .counter_bits = 16u, .filter = 6u,
                                .invert = false};
    stm32_encoder_init(&enc, &c);
    TEST_ASSERT_EQUAL_UINT(0xFFFFu, enc_tim.regs.ARR);
    /* A walk of up to +-30000 counts per read (the limit is 32767), true
     * position kept in 64 bits; the 32-bit count is its value mod 2^32. */
    int64_t truth = 0, highest = 0;
    uint32_t seed = 12345u;
    for (int i = 0; i < 160000; i++) {
        seed = seed * 1103515245u + 12345u;
        int64_t step = (int64_t)((seed >> 8) % 60001u) - 30000;
        if (i < 150000) {
            step = 30000; /* forward through 16-bit wraps and past 2^32 */
        }
        tim_model_encoder_move(&enc_tim, step);
        truth += step;
        highest = truth > highest ? truth : highest;
        TEST_ASSERT_EQUAL_HEX32((uint32_t)(uint64_t)truth, stm32_encoder_counts(&enc));
    }
    TEST_ASSERT_TRUE(highest > 0x100000000ll);

    /* Inverted direction and a 32-bit timer (TIM2/TIM5) read directly. */
    tim_model_t t32;
    tim_model_init(&t32, "TIM5");
    stm32_encoder_config_t c32 = {.tim = &t32.regs, .counter_bits = 32u, .filter = 0u,
                                  .invert = true};
    stm32_encoder_init(&enc, &c32);
    TEST_ASSERT_EQUAL_HEX32(0xFFFFFFFFu, t32.regs.ARR);
    t32.arr_active = t32.regs.ARR; /* the driver wrote ARR before the first update */
    tim_model_encoder_move(&t32, 100);
    TEST_ASSERT_EQUAL_HEX32((uint32_t)-100, stm32_encoder_counts(&enc));
}

int main(int argc, char **argv)
{
    if (UnityParseOptions(argc, argv) != 0) {
        return 1;
    }
    UNITY_BEGIN();
    RUN_TEST(test_register_offsets_match_rm0090);
    RUN_TEST(test_period_is_exact_and_fits);
    RUN_TEST(test_tick_runs_at_1khz_from_each_kernel_clock);
    RUN_TEST(test_overrun_is_seen);
    RUN_TEST(test_timer_trigger_converts_the_bridge_channel);
    RUN_TEST(test_a_conversion_that_never_completes_is_an_error);
    RUN_TEST(test_encoder_count_across_counter_wraps);
    return UNITY_END();
}
