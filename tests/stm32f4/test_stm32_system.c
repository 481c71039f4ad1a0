/*
 * Clock tree, reset cause, HardFault record, watchdog and pin setup
 * (stm32f4_clock.c, stm32f4_system.c, stm32f4_gpio.c) against the RCC,
 * flash-interface and IWDG models and the manual's tables.
 */
#include <stddef.h>
#include <stdint.h>
#include <string.h>

#include "model_flash.h"
#include "model_misc.h"
#include "stm32f4_clock.h"
#include "stm32f4_gpio.h"
#include "stm32f4_system.h"
#include "unity.h"

#define POLLS 500u
#define HSE_HZ 8000000u

static rcc_model_t g_rcc;
static flash_model_t g_flash;

void setUp(void)
{
    reg_model_reset();
    flash_model_init(&g_flash);
    rcc_model_init(&g_rcc, &g_flash.regs, HSE_HZ);
}

void tearDown(void)
{
}

static void test_register_offsets_match_rm0090(void)
{
    TEST_ASSERT_EQUAL_UINT(0x04u, offsetof(stm32_rcc_t, PLLCFGR));
    TEST_ASSERT_EQUAL_UINT(0x08u, offsetof(stm32_rcc_t, CFGR));
    TEST_ASSERT_EQUAL_UINT(0x30u, offsetof(stm32_rcc_t, AHB1ENR));
    TEST_ASSERT_EQUAL_UINT(0x40u, offsetof(stm32_rcc_t, APB1ENR));
    TEST_ASSERT_EQUAL_UINT(0x44u, offsetof(stm32_rcc_t, APB2ENR));
    TEST_ASSERT_EQUAL_UINT(0x74u, offsetof(stm32_rcc_t, CSR));
    TEST_ASSERT_EQUAL_UINT(0x0Cu, offsetof(stm32_iwdg_t, SR));
    TEST_ASSERT_EQUAL_UINT(0x0Cu, offsetof(stm32_gpio_t, PUPDR));
    TEST_ASSERT_EQUAL_UINT(0x24u, offsetof(stm32_gpio_t, AFR[1]));
}

/* RM0090 table "Number of wait states according to CPU clock (HCLK)
 * frequency", 2.7 V - 3.6 V: 0 WS up to 30 MHz, one more per 30 MHz. */
static uint32_t wait_states_from_table(uint32_t hclk_hz)
{
    const uint32_t limits_mhz[] = {30, 60, 90, 120, 150, 168};
    for (uint32_t ws = 0; ws < 6u; ws++) {
        if (hclk_hz <= limits_mhz[ws] * 1000000u) {
            return ws;
        }
    }
    return 99u;
}

static void test_pll_plan_for_8mhz_to_168mhz(void)
{
    stm32_clock_plan_t p;
    TEST_ASSERT_TRUE(stm32_clock_plan(HSE_HZ, 168000000u, &p));
    double vco_in = (double)HSE_HZ / p.pllm;
    double vco = vco_in * p.plln;
    TEST_ASSERT_TRUE(vco_in >= 1e6 && vco_in <= 2e6);
    TEST_ASSERT_TRUE(vco >= 100e6 && vco <= 432e6);
    TEST_ASSERT_EQUAL_DOUBLE(168e6, vco / p.pllp);
    TEST_ASSERT_EQUAL_DOUBLE(48e6, vco / p.pllq); /* USB OTG FS needs exactly 48 MHz */
    TEST_ASSERT_TRUE(p.pllp == 2u || p.pllp == 4u || p.pllp == 6u || p.pllp == 8u);
    TEST_ASSERT_EQUAL_UINT(wait_states_from_table(168000000u), p.flash_ws);
    TEST_ASSERT_EQUAL_UINT(4u, p.ppre1_div); /* APB1 <= 42 MHz */
    TEST_ASSERT_EQUAL_UINT(2u, p.ppre2_div); /* APB2 <= 84 MHz */
    TEST_ASSERT_FALSE(stm32_clock_plan(25000000u, 168000000u, &p)); /* 25 MHz: not 2 MHz steps */
    TEST_ASSERT_FALSE(stm32_clock_plan(HSE_HZ, 500000000u, &p));
}

static stm32_clock_config_t clock_config(void)
{
    stm32_clock_config_t c = {.hse_hz = HSE_HZ, .sysclk_hz = 168000000u, .ready_polls = POLLS};
    return c;
}

static void test_clock_tree_comes_up_at_168mhz(void)
{
    stm32_clock_config_t c = clock_config();
    stm32_clock_t clk;
    TEST_ASSERT_EQUAL_UINT(0u, stm32_clock_init(&g_rcc.regs, &g_flash.regs, &c, &clk));
    TEST_ASSERT_TRUE(clk.on_pll);
    TEST_ASSERT_EQUAL_UINT(168000000u, clk.sysclk_hz);
    TEST_ASSERT_EQUAL_UINT(42000000u, clk.pclk1_hz);
    TEST_ASSERT_EQUAL_UINT(84000000u, clk.pclk2_hz);
    TEST_ASSERT_EQUAL_UINT(84000000u, clk.tim_apb1_hz);  /* x2: APB1 divider 4 */
    TEST_ASSERT_EQUAL_UINT(168000000u, clk.tim_apb2_hz); /* x2: APB2 divider 2 */
    TEST_ASSERT_EQUAL_UINT(168000000u, rcc_model_sysclk(&g_rcc)); /* what the registers say */
    TEST_ASSERT_EQUAL_UINT(0u, g_rcc.violations); /* wait states before the switch */
    TEST_ASSERT_TRUE(g_flash.regs.ACR & STM32_FLASH_ACR_PRFTEN);
    TEST_ASSERT_EQUAL_UINT(0u, reg_model_stray_accesses());
}

static void assert_on_hsi(const stm32_clock_t *clk)
{
    TEST_ASSERT_FALSE(clk->on_pll);
    TEST_ASSERT_EQUAL_UINT(16000000u, clk->sysclk_hz);
    TEST_ASSERT_EQUAL_UINT(16000000u, clk->pclk1_hz);
    TEST_ASSERT_EQUAL_UINT(16000000u, clk->tim_apb2_hz);
}

static void test_clock_faults_fall_back_to_hsi_within_the_bound(void)
{
    stm32_clock_config_t c = clock_config();
    stm32_clock_t clk;
    g_rcc.hse_present = false; /* no crystal */
    TEST_ASSERT_EQUAL_UINT(STM32_CLOCK_FAULT_HSE,
                           stm32_clock_init(&g_rcc.regs, &g_flash.regs, &c, &clk));
    assert_on_hsi(&clk);
    TEST_ASSERT_EQUAL_UINT(16000000u, rcc_model_sysclk(&g_rcc));
    TEST_ASSERT_FALSE(g_rcc.regs.CR & STM32_RCC_CR_HSEON);
    TEST_ASSERT_LESS_OR_EQUAL(2u * POLLS + 16u, g_rcc.rm.reads);

    setUp();
    g_rcc.pll_locks = false;
    TEST_ASSERT_EQUAL_UINT(STM32_CLOCK_FAULT_PLL,
                           stm32_clock_init(&g_rcc.regs, &g_flash.regs, &c, &clk));
    assert_on_hsi(&clk);
    TEST_ASSERT_FALSE(g_rcc.regs.CR & (STM32_RCC_CR_PLLON | STM32_RCC_CR_HSEON));
    TEST_ASSERT_EQUAL_UINT(0u, g_flash.regs.ACR & STM32_FLASH_ACR_LATENCY_MASK);
    TEST_ASSERT_EQUAL_UINT(0u, g_rcc.violations);

    setUp();
    g_rcc.absent = true; /* QEMU netduinoplus2: every RCC register reads 0 */
    TEST_ASSERT_EQUAL_UINT(STM32_CLOCK_FAULT_HSE,
                           stm32_clock_init(&g_rcc.regs, &g_flash.regs, &c, &clk));
    assert_on_hsi(&clk);
    TEST_ASSERT_LESS_OR_EQUAL(2u * POLLS + 16u, g_rcc.rm.reads);

    setUp();
    c.hse_hz = 25000000u;
    TEST_ASSERT_EQUAL_UINT(STM32_CLOCK_FAULT_CONFIG,
                           stm32_clock_init(&g_rcc.regs, &g_flash.regs, &c, &clk));
    assert_on_hsi(&clk);
    TEST_ASSERT_EQUAL_UINT(0u, g_rcc.rm.writes); /* nothing touched */
}

static void test_reset_cause_classification(void)
{
    const uint32_t pin = STM32_RCC_CSR_PINRSTF;
    const struct {
        uint32_t csr;
        uint32_t cause;
    } cases[] = {
        {STM32_RCC_CSR_PORRSTF | STM32_RCC_CSR_BORRSTF | pin, HAL_RESET_POWER_ON},
        {STM32_RCC_CSR_BORRSTF | pin, HAL_RESET_BROWNOUT},
        {STM32_RCC_CSR_IWDGRSTF | pin, HAL_RESET_WATCHDOG},
        {STM32_RCC_CSR_WWDGRSTF | pin, HAL_RESET_WATCHDOG},
        {STM32_RCC_CSR_SFTRSTF | pin, HAL_RESET_SOFTWARE},
        {pin, HAL_RESET_PIN},
        {STM32_RCC_CSR_IWDGRSTF | STM32_RCC_CSR_SFTRSTF | pin,
         HAL_RESET_WATCHDOG | HAL_RESET_SOFTWARE},
        {0u, 0u},
    };
    for (size_t i = 0; i < sizeof cases / sizeof cases[0]; i++) {
        TEST_ASSERT_EQUAL_HEX32(cases[i].cause, stm32_reset_cause_from_csr(cases[i].csr));
    }
    g_rcc.regs.CSR = STM32_RCC_CSR_IWDGRSTF | pin | STM32_RCC_CSR_LSION;
    TEST_ASSERT_EQUAL_HEX32(HAL_RESET_WATCHDOG, stm32_reset_cause(&g_rcc.regs));
    TEST_ASSERT_EQUAL_HEX32(STM32_RCC_CSR_LSION, g_rcc.regs.CSR); /* flags cleared, LSI kept */
    TEST_ASSERT_EQUAL_HEX32(0u, stm32_reset_cause(&g_rcc.regs));
}

static void test_fault_record_is_reported_once_and_garbage_is_not_one(void)
{
    stm32_fault_record_t rec, out;
    memset(&rec, 0xA5, sizeof rec); /* RAM after power-on */
    TEST_ASSERT_FALSE(stm32_fault_record_take(&rec, &out));
    const uint32_t frame[8] = {1, 2, 3, 4, 12, 0x08001235u, 0x08004560u, 0x21000000u};
    const uint32_t cfsr = STM32_SCB_CFSR_BFARVALID | 0x0400u; /* precise bus fault */
    stm32_fault_record_save(&rec, frame, cfsr, 0x40000000u, 0xDEAD0000u, 0x20020000u);
    TEST_ASSERT_TRUE(stm32_fault_record_take(&rec, &out));
    TEST_ASSERT_EQUAL_HEX32(0x08004560u, out.pc);
    TEST_ASSERT_EQUAL_HEX32(0x08001235u, out.lr);
    TEST_ASSERT_EQUAL_HEX32(0x21000000u, out.xpsr);
    TEST_ASSERT_EQUAL_HEX32(cfsr, out.cfsr);
    TEST_ASSERT_EQUAL_HEX32(0x40000000u, out.hfsr);
    TEST_ASSERT_EQUAL_HEX32(0x20020000u, out.bfar);
    TEST_ASSERT_EQUAL_HEX32(0u, out.mmfar); /* MMARVALID not set: not reported */
    TEST_ASSERT_FALSE(stm32_fault_record_take(&rec, &out)); /* once */

    stm32_fault_record_save(&rec, frame, cfsr, 0u, 0u, 0u);
    rec.pc ^= 0x10u; /* one flipped bit */
    TEST_ASSERT_FALSE(stm32_fault_record_take(&rec, &out));
}

static void test_watchdog_start(void)
{
    iwdg_model_t w;
    iwdg_model_init(&w);
    TEST_ASSERT_EQUAL_INT(HAL_OK, stm32_iwdg_start(&w.regs, 3u, 1499u, POLLS));
    TEST_ASSERT_TRUE(w.started);
    TEST_ASSERT_EQUAL_UINT(3u, w.regs.PR);
    TEST_ASSERT_EQUAL_UINT(1499u, w.regs.RLR);
    TEST_ASSERT_EQUAL_UINT(0u, w.violations);
    uint32_t r = w.reloads;
    stm32_iwdg_reload(&w.regs);
    TEST_ASSERT_EQUAL_UINT(r + 1u, w.reloads);
    TEST_ASSERT_EQUAL_INT(HAL_ERR_RANGE, stm32_iwdg_start(&w.regs, 7u, 100u, POLLS));
    TEST_ASSERT_EQUAL_INT(HAL_ERR_RANGE, stm32_iwdg_start(&w.regs, 3u, 4096u, POLLS));
    w.busy_reads = 10u * POLLS; /* update flags stuck */
    uint32_t reads0 = w.rm.reads;
    TEST_ASSERT_EQUAL_INT(HAL_ERR_IO, stm32_iwdg_start(&w.regs, 3u, 1499u, POLLS));
    TEST_ASSERT_EQUAL_UINT(POLLS, w.rm.reads - reads0);
}

static void test_pin_table_sets_mode_alternate_function_and_pull(void)
{
    stm32_gpio_t ports[STM32_GPIO_PORTS];
    memset(ports, 0, sizeof ports);
    ram_model_t pm;
    ram_model_init(&pm, "GPIO", ports, sizeof ports);
    stm32_gpio_t *p[STM32_GPIO_PORTS];
    for (size_t i = 0; i < STM32_GPIO_PORTS; i++) {
        p[i] = &ports[i];
    }
    const stm32_pin_t pins[] = {
        {1, 8, STM32_GPIO_MODE_AF, 9, STM32_GPIO_PULL_UP, 0, "CAN1_RX"},
        {1, 9, STM32_GPIO_MODE_AF, 9, 0, 2, "CAN1_TX"},
        {1, 4, STM32_GPIO_MODE_AF, 2, 0, 0, "TIM3_CH1"},
        {1, 5, STM32_GPIO_MODE_AF, 2, 0, 0, "TIM3_CH2"},
        {0, 3, STM32_GPIO_MODE_ANALOG, 0, 0, 0, "ADC123_IN3"},
    };
    TEST_ASSERT_EQUAL_INT(0, stm32_gpio_setup(&g_rcc.regs, p, pins, 5u));
    /* Hand-computed from RM0090 8.4: two MODER bits per pin (10 = AF,
     * 11 = analog), four AFR bits per pin, PUPDR 01 = pull-up. */
    TEST_ASSERT_EQUAL_HEX32(0x000A0A00u, ports[1].MODER);
    TEST_ASSERT_EQUAL_HEX32(0x00220000u, ports[1].AFR[0]);
    TEST_ASSERT_EQUAL_HEX32(0x00000099u, ports[1].AFR[1]);
    TEST_ASSERT_EQUAL_HEX32(0x00010000u, ports[1].PUPDR);
    TEST_ASSERT_EQUAL_HEX32(0x00080000u, ports[1].OSPEEDR); /* PB9 fast (10) */
    TEST_ASSERT_EQUAL_HEX32(0x000000C0u, ports[0].MODER);
    TEST_ASSERT_EQUAL_HEX32(0x3u, g_rcc.regs.AHB1ENR & 0x1FFu); /* GPIOA and GPIOB clocks */
    const stm32_pin_t bad = {9, 0, STM32_GPIO_MODE_AF, 0, 0, 0, "no port J"};
    TEST_ASSERT_EQUAL_INT(-1, stm32_gpio_setup(&g_rcc.regs, p, &bad, 1u));
}

int main(int argc, char **argv)
{
    if (UnityParseOptions(argc, argv) != 0) {
        return 1;
    }
    UNITY_BEGIN();
    RUN_TEST(test_register_offsets_match_rm0090);
    RUN_TEST(test_pll_plan_for_8mhz_to_168mhz);
    RUN_TEST(test_clock_tree_comes_up_at_168mhz);
    RUN_TEST(test_clock_faults_fall_back_to_hsi_within_the_bound);
    RUN_TEST(test_reset_cause_classification);
    RUN_TEST(test_fault_record_is_reported_once_and_garbage_is_not_one);
    RUN_TEST(test_watchdog_start);
    RUN_TEST(test_pin_table_sets_mode_alternate_function_and_pull);
    return UNITY_END();
}
