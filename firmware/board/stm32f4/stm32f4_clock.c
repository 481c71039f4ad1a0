/* stm32f4_clock: see stm32f4_clock.h. */
#include "stm32f4_clock.h"

#define PLLN_MIN 50u
#define PLLN_MAX 432u
#define VCO_OUT_MIN_HZ 100000000u
#define VCO_OUT_MAX_HZ 432000000u
#define PLLQ_MIN 2u
#define PLLQ_MAX 15u

static uint32_t ppre_code(uint32_t div)
{
    switch (div) {
    case 2: return STM32_RCC_PPRE_DIV2;
    case 4: return STM32_RCC_PPRE_DIV4;
    case 8: return STM32_RCC_PPRE_DIV8;
    case 16: return STM32_RCC_PPRE_DIV16;
    default: return STM32_RCC_PPRE_DIV1;
    }
}

/* Smallest power-of-two divider that keeps the bus at or below its limit. */
static uint32_t bus_divider(uint32_t hclk_hz, uint32_t max_hz)
{
    uint32_t div = 1u;
    while (hclk_hz / div > max_hz && div < 16u) {
        div *= 2u;
    }
    return div;
}

bool stm32_clock_plan(uint32_t hse_hz, uint32_t sysclk_hz, stm32_clock_plan_t *plan)
{
    if (hse_hz == 0u || hse_hz % STM32_PLL_VCO_IN_HZ != 0u || sysclk_hz == 0u) {
        return false;
    }
    uint32_t m = hse_hz / STM32_PLL_VCO_IN_HZ;
    uint32_t p = 2u;
    uint64_t vco = (uint64_t)sysclk_hz * p;
    while (vco < VCO_OUT_MIN_HZ && p < 8u) { /* low clocks: a larger output divider */
        p += 2u;
        vco = (uint64_t)sysclk_hz * p;
    }
    if (m < 2u || m > 63u || vco % STM32_PLL_VCO_IN_HZ != 0u || vco > VCO_OUT_MAX_HZ ||
        vco < VCO_OUT_MIN_HZ) {
        return false;
    }
    uint32_t n = (uint32_t)(vco / STM32_PLL_VCO_IN_HZ);
    uint32_t q = (uint32_t)((vco + STM32_USB_HZ - 1u) / STM32_USB_HZ); /* USB <= 48 MHz */
    if (n < PLLN_MIN || n > PLLN_MAX || q < PLLQ_MIN || q > PLLQ_MAX) {
        return false;
    }
    plan->pllm = m;
    plan->plln = n;
    plan->pllp = p;
    plan->pllq = q;
    plan->ppre1_div = bus_divider(sysclk_hz, STM32_PCLK1_MAX_HZ);
    plan->ppre2_div = bus_divider(sysclk_hz, STM32_PCLK2_MAX_HZ);
    plan->flash_ws = (sysclk_hz - 1u) / STM32_FLASH_HZ_PER_WS;
    return true;
}

static void fill(stm32_clock_t *out, uint32_t sysclk_hz, uint32_t div1, uint32_t div2, bool pll)
{
    out->sysclk_hz = sysclk_hz;
    out->pclk1_hz = sysclk_hz / div1;
    out->pclk2_hz = sysclk_hz / div2;
    out->tim_apb1_hz = div1 == 1u ? out->pclk1_hz : 2u * out->pclk1_hz;
    out->tim_apb2_hz = div2 == 1u ? out->pclk2_hz : 2u * out->pclk2_hz;
    out->on_pll = pll;
}

void stm32_clock_hsi(stm32_clock_t *out)
{
    fill(out, STM32_HSI_HZ, 1u, 1u, false);
    out->faults = 0u;
}

/* Back to the reset state: HSI selected, prescalers 1, PLL and HSE off,
 * wait states restored last (they may only go down once the clock has). */
static uint32_t fall_back(stm32_rcc_t *rcc, stm32_flash_t *flash, const stm32_clock_config_t *cfg,
                          stm32_clock_t *out, uint32_t faults)
{
    STM32_CLR(rcc->CFGR, STM32_RCC_CFGR_SW_MASK);
    (void)stm32_wait(&rcc->CFGR, STM32_RCC_CFGR_SW_MASK << STM32_RCC_CFGR_SWS_POS,
                     STM32_RCC_CFGR_SW_HSI << STM32_RCC_CFGR_SWS_POS, cfg->ready_polls);
    STM32_WR(rcc->CFGR, 0u);
    STM32_CLR(rcc->CR, STM32_RCC_CR_PLLON | STM32_RCC_CR_HSEON);
    STM32_CLR(flash->ACR, STM32_FLASH_ACR_LATENCY_MASK);
    stm32_clock_hsi(out);
    out->faults = faults;
    return faults;
}

uint32_t stm32_clock_init(stm32_rcc_t *rcc, stm32_flash_t *flash, const stm32_clock_config_t *cfg,
                          stm32_clock_t *out)
{
    stm32_clock_plan_t plan;
    if (!stm32_clock_plan(cfg->hse_hz, cfg->sysclk_hz, &plan)) {
        stm32_clock_hsi(out);
        out->faults = STM32_CLOCK_FAULT_CONFIG;
        return out->faults;
    }
    STM32_SET(rcc->CR, STM32_RCC_CR_HSEON);
    if (!stm32_wait(&rcc->CR, STM32_RCC_CR_HSERDY, STM32_RCC_CR_HSERDY, cfg->ready_polls)) {
        return fall_back(rcc, flash, cfg, out, STM32_CLOCK_FAULT_HSE);
    }
    /* PLLCFGR may only be written with the PLL off. */
    STM32_CLR(rcc->CR, STM32_RCC_CR_PLLON);
    STM32_WR(rcc->PLLCFGR, (plan.pllm << STM32_RCC_PLLCFGR_PLLM_POS) |
                               (plan.plln << STM32_RCC_PLLCFGR_PLLN_POS) |
                               (((plan.pllp / 2u) - 1u) << STM32_RCC_PLLCFGR_PLLP_POS) |
                               STM32_RCC_PLLCFGR_PLLSRC_HSE |
                               (plan.pllq << STM32_RCC_PLLCFGR_PLLQ_POS));
    STM32_SET(rcc->CR, STM32_RCC_CR_PLLON);
    if (!stm32_wait(&rcc->CR, STM32_RCC_CR_PLLRDY, STM32_RCC_CR_PLLRDY, cfg->ready_polls)) {
        return fall_back(rcc, flash, cfg, out, STM32_CLOCK_FAULT_PLL);
    }
    /* Wait states before the faster clock (RM0090 3.5.1: check by reading back). */
    STM32_WR(flash->ACR, plan.flash_ws | STM32_FLASH_ACR_PRFTEN | STM32_FLASH_ACR_ICEN |
                             STM32_FLASH_ACR_DCEN);
    if ((STM32_RD(flash->ACR) & STM32_FLASH_ACR_LATENCY_MASK) != plan.flash_ws) {
        return fall_back(rcc, flash, cfg, out, STM32_CLOCK_FAULT_FLASH);
    }
    STM32_WR(rcc->CFGR, (ppre_code(plan.ppre1_div) << STM32_RCC_CFGR_PPRE1_POS) |
                            (ppre_code(plan.ppre2_div) << STM32_RCC_CFGR_PPRE2_POS) |
                            STM32_RCC_CFGR_SW_PLL);
    if (!stm32_wait(&rcc->CFGR, STM32_RCC_CFGR_SW_MASK << STM32_RCC_CFGR_SWS_POS,
                    STM32_RCC_CFGR_SW_PLL << STM32_RCC_CFGR_SWS_POS, cfg->ready_polls)) {
        return fall_back(rcc, flash, cfg, out, STM32_CLOCK_FAULT_SWITCH);
    }
    fill(out, cfg->sysclk_hz, plan.ppre1_div, plan.ppre2_div, true);
    out->faults = 0u;
    return 0u;
}
