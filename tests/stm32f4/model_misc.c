/* model_misc: see model_misc.h. */
#include "model_misc.h"

#include <string.h>

/* ------------------------------------------------------------- RAM block */
static uint32_t ram_read(reg_model_t *rm, size_t off)
{
    return *reg_at(rm->base, off);
}

static void ram_write(reg_model_t *rm, size_t off, uint32_t v)
{
    *reg_at(rm->base, off) = v;
}

void ram_model_init(ram_model_t *m, const char *name, volatile void *block, size_t size)
{
    memset(m, 0, sizeof *m);
    m->rm.name = name;
    m->rm.base = block;
    m->rm.size = size;
    m->rm.read = ram_read;
    m->rm.write = ram_write;
    reg_model_add(&m->rm);
}

/* ----------------------------------------------------------------- timer */
#define TOFF(field) offsetof(stm32_tim_t, field)

static void update_event(tim_model_t *m, bool from_ug)
{
    m->psc_active = m->regs.PSC;
    m->arr_active = m->regs.ARR;
    m->prescale_count = 0u;
    m->updates++;
    if (!(from_ug && (m->regs.CR1 & STM32_TIM_CR1_URS))) {
        m->regs.SR |= STM32_TIM_SR_UIF;
    }
    if ((m->regs.CR2 & STM32_TIM_CR2_MMS_MASK) == STM32_TIM_CR2_MMS_UPDATE && m->trgo) {
        m->trgo(m->trgo_ctx, m->trgo_source);
    }
}

static uint32_t tim_read(reg_model_t *rm, size_t off)
{
    tim_model_t *m = (tim_model_t *)rm;
    return *reg_at(&m->regs, off);
}

static void tim_write(reg_model_t *rm, size_t off, uint32_t v)
{
    tim_model_t *m = (tim_model_t *)rm;
    if (off == TOFF(SR)) {
        m->regs.SR &= v; /* rc_w0 */
    } else if (off == TOFF(EGR)) {
        if (v & STM32_TIM_EGR_UG) {
            m->regs.CNT = 0u;
            update_event(m, true);
        }
    } else if (off == TOFF(ARR)) {
        m->regs.ARR = v;
        if (!(m->regs.CR1 & STM32_TIM_CR1_ARPE)) {
            m->arr_active = v;
        }
    } else if (off == TOFF(PSC)) {
        m->regs.PSC = v & 0xFFFFu; /* active only from the next update event */
    } else {
        *reg_at(&m->regs, off) = v;
    }
}

void tim_model_init(tim_model_t *m, const char *name)
{
    memset(m, 0, sizeof *m);
    m->rm.name = name;
    m->rm.base = &m->regs;
    m->rm.size = sizeof m->regs;
    m->rm.read = tim_read;
    m->rm.write = tim_write;
    m->regs.ARR = 0xFFFFu;
    m->arr_active = 0xFFFFu;
    reg_model_add(&m->rm);
}

void tim_model_clock(tim_model_t *m, uint64_t n)
{
    if (!(m->regs.CR1 & STM32_TIM_CR1_CEN) ||
        (m->regs.SMCR & STM32_TIM_SMCR_SMS_MASK) != 0u) {
        return;
    }
    while (n > 0u) {
        uint64_t div = (uint64_t)m->psc_active + 1u;
        uint64_t to_overflow = ((uint64_t)m->arr_active - m->regs.CNT + 1u) * div -
                               m->prescale_count;
        if (n < to_overflow) {
            uint64_t total = m->prescale_count + n;
            m->regs.CNT += (uint32_t)(total / div);
            m->prescale_count = total % div;
            return;
        }
        n -= to_overflow;
        m->regs.CNT = 0u;
        update_event(m, false);
    }
}

void tim_model_encoder_move(tim_model_t *m, int64_t delta)
{
    if (!(m->regs.CR1 & STM32_TIM_CR1_CEN) ||
        (m->regs.SMCR & STM32_TIM_SMCR_SMS_MASK) != STM32_TIM_SMCR_SMS_ENCODER3 ||
        (m->regs.CCMR1 & 0x303u) != (STM32_TIM_CCMR1_CC1S_TI1 | STM32_TIM_CCMR1_CC2S_TI2)) {
        return;
    }
    if (m->regs.CCER & STM32_TIM_CCER_CC1P) {
        delta = -delta; /* TI1 inverted: the other direction */
    }
    int64_t period = (int64_t)m->arr_active + 1;
    int64_t c = ((int64_t)m->regs.CNT + delta) % period;
    m->regs.CNT = (uint32_t)(c < 0 ? c + period : c);
}

/* ------------------------------------------------------------------- ADC */
#define AOFF(field) offsetof(stm32_adc_t, field)

static void adc_start_injected(adc_model_t *m)
{
    m->converting = true;
    m->conv_left = m->conv_reads;
    m->regs.SR |= STM32_ADC_SR_JSTRT;
}

static void adc_finish(adc_model_t *m)
{
    uint32_t jl = (m->regs.JSQR >> STM32_ADC_JSQR_JL_POS) & 3u;
    for (uint32_t k = 0; k <= jl; k++) {
        uint32_t slot = 3u - jl + k; /* JSQ(4-JL) .. JSQ4 */
        uint32_t ch = (m->regs.JSQR >> (5u * slot)) & 0x1Fu;
        int32_t v = (int32_t)m->input[ch < 19u ? ch : 0u];
        if (!(m->regs.CR2 & STM32_ADC_CR2_ALIGN)) {
            v -= (int32_t)(m->regs.JOFR[k] & 0xFFFu);
        }
        m->regs.JDR[k] = (uint32_t)(uint16_t)(int16_t)v;
    }
    m->converting = false;
    m->conversions++;
    m->regs.SR |= STM32_ADC_SR_JEOC;
}

static uint32_t adc_read(reg_model_t *rm, size_t off)
{
    adc_model_t *m = (adc_model_t *)rm;
    if (off == AOFF(SR) && m->converting && !m->never_completes) {
        if (m->conv_left > 0u) {
            m->conv_left--;
        }
        if (m->conv_left == 0u) {
            adc_finish(m);
        }
    }
    return *reg_at(&m->regs, off);
}

static void adc_write(reg_model_t *rm, size_t off, uint32_t v)
{
    adc_model_t *m = (adc_model_t *)rm;
    if (off == AOFF(SR)) {
        m->regs.SR &= (v | ~0x3Fu); /* rc_w0 */
    } else if (off == AOFF(CR2)) {
        m->regs.CR2 = v & ~STM32_ADC_CR2_JSWSTART;
        if ((v & STM32_ADC_CR2_JSWSTART) && (v & STM32_ADC_CR2_ADON)) {
            adc_start_injected(m);
        }
    } else if (off >= AOFF(JDR) && off < AOFF(DR)) {
        /* read only */
    } else {
        *reg_at(&m->regs, off) = v;
    }
}

void adc_model_trigger(void *ctx, uint32_t source)
{
    adc_model_t *m = ctx;
    uint32_t cr2 = m->regs.CR2;
    if (!(cr2 & STM32_ADC_CR2_ADON) || (cr2 & STM32_ADC_CR2_JEXTEN_MASK) == 0u ||
        ((cr2 & STM32_ADC_CR2_JEXTSEL_MASK) >> STM32_ADC_CR2_JEXTSEL_POS) != source) {
        m->triggers_ignored++;
        return;
    }
    adc_start_injected(m);
}

void adc_model_init(adc_model_t *m)
{
    memset(m, 0, sizeof *m);
    m->rm.name = "ADC1";
    m->rm.base = &m->regs;
    m->rm.size = sizeof m->regs;
    m->rm.read = adc_read;
    m->rm.write = adc_write;
    m->conv_reads = 4u;
    reg_model_add(&m->rm);
}

/* ------------------------------------------------------------------- RCC */
#define ROFF(field) offsetof(stm32_rcc_t, field)

static void rcc_violation(rcc_model_t *m, const char *what)
{
    m->violations++;
    m->last_violation = what;
}

static uint32_t pll_out_hz(const rcc_model_t *m)
{
    uint32_t c = m->regs.PLLCFGR;
    uint32_t pm = c & 0x3Fu, pn = (c >> 6) & 0x1FFu, pp = 2u * (((c >> 16) & 3u) + 1u);
    uint32_t src = (c & STM32_RCC_PLLCFGR_PLLSRC_HSE) ? m->hse_hz : STM32_HSI_HZ_MODEL;
    if (pm < 2u || pn < 50u || pn > 432u) {
        return 0u;
    }
    uint64_t vco = (uint64_t)src / pm * pn;
    if ((uint64_t)src / pm < 1000000u || (uint64_t)src / pm > 2000000u || vco < 100000000u ||
        vco > 432000000u) {
        return 0u;
    }
    return (uint32_t)(vco / pp);
}

uint32_t rcc_model_sysclk(const rcc_model_t *m)
{
    switch ((m->regs.CFGR >> STM32_RCC_CFGR_SWS_POS) & 3u) {
    case STM32_RCC_CFGR_SW_HSE: return m->hse_hz;
    case STM32_RCC_CFGR_SW_PLL: return pll_out_hz(m);
    default: return STM32_HSI_HZ_MODEL;
    }
}

static uint32_t ppre_div(uint32_t code)
{
    return (code & 4u) ? (2u << (code & 3u)) : 1u;
}

static void check_switch(rcc_model_t *m)
{
    uint32_t hz = pll_out_hz(m);
    uint32_t need_ws = (hz - 1u) / 30000000u;
    if (m->flash != NULL && (m->flash->ACR & 0xFu) < need_ws) {
        rcc_violation(m, "switched to the PLL with too few flash wait states");
    }
    if (hz / ppre_div((m->regs.CFGR >> STM32_RCC_CFGR_PPRE1_POS) & 7u) > 42000000u ||
        hz / ppre_div((m->regs.CFGR >> STM32_RCC_CFGR_PPRE2_POS) & 7u) > 84000000u) {
        rcc_violation(m, "APB clock above its maximum");
    }
    if (hz > 168000000u) {
        rcc_violation(m, "system clock above 168 MHz");
    }
}

static uint32_t rcc_read(reg_model_t *rm, size_t off)
{
    rcc_model_t *m = (rcc_model_t *)rm;
    if (m->absent) {
        return 0u;
    }
    if (off == ROFF(CR)) {
        if ((m->regs.CR & STM32_RCC_CR_HSEON) && m->hse_present && m->hse_left > 0u &&
            --m->hse_left == 0u) {
            m->regs.CR |= STM32_RCC_CR_HSERDY;
        }
        if ((m->regs.CR & STM32_RCC_CR_PLLON) && m->pll_left > 0u && --m->pll_left == 0u) {
            m->regs.CR |= STM32_RCC_CR_PLLRDY;
        }
    } else if (off == ROFF(CFGR) && m->sw_left > 0u && --m->sw_left == 0u) {
        if (m->sw_target == STM32_RCC_CFGR_SW_PLL) {
            check_switch(m);
        }
        m->regs.CFGR = (m->regs.CFGR & ~(3u << STM32_RCC_CFGR_SWS_POS)) |
                       (m->sw_target << STM32_RCC_CFGR_SWS_POS);
    }
    return *reg_at(&m->regs, off);
}

static void rcc_write(reg_model_t *rm, size_t off, uint32_t v)
{
    rcc_model_t *m = (rcc_model_t *)rm;
    if (m->absent) {
        return;
    }
    if (off == ROFF(CR)) {
        uint32_t old = m->regs.CR;
        m->regs.CR = (old & (STM32_RCC_CR_HSIRDY | STM32_RCC_CR_HSERDY | STM32_RCC_CR_PLLRDY)) |
                     (v & ~(STM32_RCC_CR_HSIRDY | STM32_RCC_CR_HSERDY | STM32_RCC_CR_PLLRDY));
        if ((v & STM32_RCC_CR_HSEON) && !(old & STM32_RCC_CR_HSEON)) {
            m->hse_left = m->ready_reads;
        }
        if (!(v & STM32_RCC_CR_HSEON)) {
            m->regs.CR &= ~STM32_RCC_CR_HSERDY;
        }
        if ((v & STM32_RCC_CR_PLLON) && !(old & STM32_RCC_CR_PLLON)) {
            bool src_ready = (m->regs.PLLCFGR & STM32_RCC_PLLCFGR_PLLSRC_HSE)
                                 ? (m->regs.CR & STM32_RCC_CR_HSERDY) != 0u
                                 : true;
            m->pll_left = (src_ready && m->pll_locks && pll_out_hz(m) != 0u) ? m->ready_reads : 0u;
        }
        if (!(v & STM32_RCC_CR_PLLON)) {
            m->regs.CR &= ~STM32_RCC_CR_PLLRDY;
            m->pll_left = 0u;
        }
    } else if (off == ROFF(PLLCFGR)) {
        if (m->regs.CR & STM32_RCC_CR_PLLON) {
            rcc_violation(m, "PLLCFGR written with the PLL on");
            return;
        }
        m->regs.PLLCFGR = v;
    } else if (off == ROFF(CFGR)) {
        uint32_t sws = m->regs.CFGR & (3u << STM32_RCC_CFGR_SWS_POS);
        m->regs.CFGR = (v & ~(3u << STM32_RCC_CFGR_SWS_POS)) | sws;
        uint32_t sw = v & STM32_RCC_CFGR_SW_MASK;
        bool ready = sw == STM32_RCC_CFGR_SW_HSI ||
                     (sw == STM32_RCC_CFGR_SW_HSE && (m->regs.CR & STM32_RCC_CR_HSERDY)) ||
                     (sw == STM32_RCC_CFGR_SW_PLL && (m->regs.CR & STM32_RCC_CR_PLLRDY));
        if (ready && sw != (sws >> STM32_RCC_CFGR_SWS_POS)) {
            m->sw_target = sw;
            m->sw_left = m->ready_reads;
        }
    } else if (off == ROFF(CSR)) {
        m->regs.CSR = (m->regs.CSR & 0xFE000000u) | (v & 0x01FFFFFFu);
        if (v & STM32_RCC_CSR_RMVF) {
            m->regs.CSR &= 0x00FFFFFFu & ~STM32_RCC_CSR_RMVF;
        }
    } else {
        *reg_at(&m->regs, off) = v;
    }
}

void rcc_model_init(rcc_model_t *m, const stm32_flash_t *flash, uint32_t hse_hz)
{
    memset(m, 0, sizeof *m);
    m->rm.name = "RCC";
    m->rm.base = &m->regs;
    m->rm.size = sizeof m->regs;
    m->rm.read = rcc_read;
    m->rm.write = rcc_write;
    m->regs.CR = 0x00000083u; /* HSION, HSIRDY */
    m->regs.PLLCFGR = 0x24003010u;
    m->hse_present = true;
    m->pll_locks = true;
    m->ready_reads = 5u;
    m->flash = flash;
    m->hse_hz = hse_hz;
    reg_model_add(&m->rm);
}

/* ------------------------------------------------------------------ IWDG */
#define IOFF(field) offsetof(stm32_iwdg_t, field)

static uint32_t iwdg_read(reg_model_t *rm, size_t off)
{
    iwdg_model_t *m = (iwdg_model_t *)rm;
    if (off == IOFF(SR) && m->busy_left > 0u && --m->busy_left == 0u) {
        m->regs.SR = 0u;
    }
    return *reg_at(&m->regs, off);
}

static void iwdg_write(reg_model_t *rm, size_t off, uint32_t v)
{
    iwdg_model_t *m = (iwdg_model_t *)rm;
    if (off == IOFF(KR)) {
        m->access = (v & 0xFFFFu) == STM32_IWDG_KEY_ACCESS;
        if ((v & 0xFFFFu) == STM32_IWDG_KEY_ENABLE) {
            m->started = true;
        }
        if ((v & 0xFFFFu) == STM32_IWDG_KEY_RELOAD) {
            m->reloads++;
        }
    } else if (off == IOFF(PR) || off == IOFF(RLR)) {
        if (!m->access) {
            m->violations++;
            return;
        }
        *reg_at(&m->regs, off) = v;
        m->regs.SR |= off == IOFF(PR) ? STM32_IWDG_SR_PVU : STM32_IWDG_SR_RVU;
        m->busy_left = m->busy_reads;
    }
}

void iwdg_model_init(iwdg_model_t *m)
{
    memset(m, 0, sizeof *m);
    m->rm.name = "IWDG";
    m->rm.base = &m->regs;
    m->rm.size = sizeof m->regs;
    m->rm.read = iwdg_read;
    m->rm.write = iwdg_write;
    m->regs.RLR = 0xFFFu;
    m->busy_reads = 3u;
    reg_model_add(&m->rm);
}
