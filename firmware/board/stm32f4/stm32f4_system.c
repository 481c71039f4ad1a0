/* stm32f4_system: see stm32f4_system.h. */
#include "stm32f4_system.h"

#define IWDG_PR_MAX 6u
#define IWDG_RELOAD_MAX 4095u

uint32_t stm32_reset_cause_from_csr(uint32_t csr)
{
    uint32_t cause = 0u;
    if ((csr & (STM32_RCC_CSR_IWDGRSTF | STM32_RCC_CSR_WWDGRSTF)) != 0u) {
        cause |= HAL_RESET_WATCHDOG;
    }
    if ((csr & STM32_RCC_CSR_SFTRSTF) != 0u) {
        cause |= HAL_RESET_SOFTWARE;
    }
    if ((csr & STM32_RCC_CSR_PORRSTF) != 0u) {
        cause |= HAL_RESET_POWER_ON;
    } else if ((csr & STM32_RCC_CSR_BORRSTF) != 0u) {
        cause |= HAL_RESET_BROWNOUT;
    }
    if (cause == 0u && (csr & STM32_RCC_CSR_PINRSTF) != 0u) {
        cause = HAL_RESET_PIN;
    }
    return cause;
}

uint32_t stm32_reset_cause(stm32_rcc_t *rcc)
{
    uint32_t csr = STM32_RD(rcc->CSR);
    STM32_SET(rcc->CSR, STM32_RCC_CSR_RMVF);
    return stm32_reset_cause_from_csr(csr);
}

static uint32_t record_check(const stm32_fault_record_t *r)
{
    return ~(r->magic + r->pc + r->lr + r->xpsr + r->sp + r->cfsr + r->hfsr + r->mmfar +
             r->bfar);
}

void stm32_fault_record_save(stm32_fault_record_t *rec, const uint32_t *frame, uint32_t cfsr,
                             uint32_t hfsr, uint32_t mmfar, uint32_t bfar)
{
    enum { FRAME_LR = 5, FRAME_PC = 6, FRAME_XPSR = 7 };
    rec->magic = STM32_FAULT_MAGIC;
    rec->pc = frame[FRAME_PC];
    rec->lr = frame[FRAME_LR];
    rec->xpsr = frame[FRAME_XPSR];
    rec->sp = (uint32_t)(uintptr_t)frame;
    rec->cfsr = cfsr;
    rec->hfsr = hfsr;
    rec->mmfar = (cfsr & STM32_SCB_CFSR_MMARVALID) != 0u ? mmfar : 0u;
    rec->bfar = (cfsr & STM32_SCB_CFSR_BFARVALID) != 0u ? bfar : 0u;
    rec->check = record_check(rec);
}

bool stm32_fault_record_take(stm32_fault_record_t *rec, stm32_fault_record_t *out)
{
    bool valid = rec->magic == STM32_FAULT_MAGIC && rec->check == record_check(rec);
    if (valid) {
        *out = *rec;
    }
    rec->magic = 0u;
    rec->check = 0u;
    return valid;
}

int stm32_iwdg_start(stm32_iwdg_t *iwdg, uint32_t pr, uint32_t reload, uint32_t polls)
{
    if (pr > IWDG_PR_MAX || reload > IWDG_RELOAD_MAX) {
        return HAL_ERR_RANGE;
    }
    STM32_WR(iwdg->KR, STM32_IWDG_KEY_ENABLE);  /* starts it (and the LSI) */
    STM32_WR(iwdg->KR, STM32_IWDG_KEY_ACCESS);  /* unlocks PR and RLR */
    STM32_WR(iwdg->PR, pr);
    STM32_WR(iwdg->RLR, reload);
    int ok = stm32_wait(&iwdg->SR, STM32_IWDG_SR_PVU | STM32_IWDG_SR_RVU, 0u, polls);
    STM32_WR(iwdg->KR, STM32_IWDG_KEY_RELOAD);
    return ok ? HAL_OK : HAL_ERR_IO;
}

void stm32_iwdg_reload(stm32_iwdg_t *iwdg)
{
    STM32_WR(iwdg->KR, STM32_IWDG_KEY_RELOAD);
}

void stm32_reboot(void)
{
#if defined(__arm__)
    __asm__ volatile("dsb" ::: "memory");
    STM32_SCB_AIRCR = STM32_SCB_AIRCR_VECTKEY | STM32_SCB_AIRCR_SYSRESETREQ;
    __asm__ volatile("dsb" ::: "memory");
    for (;;) {
        __asm__ volatile("nop");
    }
#endif
}
