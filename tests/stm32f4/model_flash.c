/* model_flash: see model_flash.h. */
#include "model_flash.h"

#include <string.h>

#define OFF(field) offsetof(stm32_flash_t, field)
#define CR_RESET 0x80000000u  /* LOCK */

static void violation(flash_model_t *m, const char *what)
{
    m->violations++;
    m->last_violation = what;
}

static void start_erase(flash_model_t *m, uint32_t cr)
{
    uint32_t snb = (cr & STM32_FLASH_CR_SNB_MASK) >> STM32_FLASH_CR_SNB_POS;
    if (m->regs.SR & STM32_FLASH_SR_BSY) {
        m->regs.SR |= STM32_FLASH_SR_PGSERR;
        return;
    }
    if (snb < FLASH_MODEL_FIRST_SNB || snb >= FLASH_MODEL_FIRST_SNB + FLASH_MODEL_SECTORS) {
        violation(m, "erase of a sector outside the NVM region (code would be lost)");
        return;
    }
    uint32_t s = snb - FLASH_MODEL_FIRST_SNB;
    if (m->wrp_sectors & (1u << s)) {
        m->regs.SR |= STM32_FLASH_SR_WRPERR;
        return;
    }
    m->erases++;
    if (m->inject_erase_error) {
        m->regs.SR |= m->inject_erase_error;
        m->inject_erase_error = 0u;
        memset(&m->mem[s * FLASH_MODEL_SECTOR_BYTES], 0x00, 16u); /* half-erased: garbage */
        return;
    }
    memset(&m->mem[s * FLASH_MODEL_SECTOR_BYTES], 0xFF, FLASH_MODEL_SECTOR_BYTES);
    m->regs.SR |= STM32_FLASH_SR_BSY;
    m->busy_left = m->erase_busy_reads;
}

static uint32_t read_reg(reg_model_t *rm, size_t off)
{
    flash_model_t *m = (flash_model_t *)rm;
    if (off == OFF(SR) && (m->regs.SR & STM32_FLASH_SR_BSY) && !m->busy_forever) {
        if (m->busy_left > 0u) {
            m->busy_left--;
        }
        if (m->busy_left == 0u) {
            m->regs.SR &= ~STM32_FLASH_SR_BSY;
            m->regs.SR |= STM32_FLASH_SR_EOP;
        }
    }
    return *reg_at(&m->regs, off);
}

static void write_reg(reg_model_t *rm, size_t off, uint32_t v)
{
    flash_model_t *m = (flash_model_t *)rm;
    if (off == OFF(KEYR)) {
        if (!(m->regs.CR & STM32_FLASH_CR_LOCK) || m->locked_until_reset) {
            violation(m, "KEYR written while unlocked or after a bad key");
            m->locked_until_reset = true;
            return;
        }
        if (m->key_state == 0u && v == STM32_FLASH_KEY1) {
            m->key_state = 1u;
        } else if (m->key_state == 1u && v == STM32_FLASH_KEY2) {
            m->key_state = 0u;
            m->regs.CR &= ~STM32_FLASH_CR_LOCK;
        } else {
            m->locked_until_reset = true; /* bus error; locked until reset */
        }
    } else if (off == OFF(CR)) {
        if (m->regs.CR & STM32_FLASH_CR_LOCK) {
            return; /* ignored while locked */
        }
        if ((m->regs.SR & STM32_FLASH_SR_BSY) && v != m->regs.CR) {
            violation(m, "FLASH_CR changed while BSY");
        }
        m->regs.CR = v & 0x8301037Fu;
        if ((v & STM32_FLASH_CR_STRT) && (v & STM32_FLASH_CR_SER)) {
            start_erase(m, v);
        }
        m->regs.CR &= ~STM32_FLASH_CR_STRT; /* STRT reads back 0 once started */
    } else if (off == OFF(SR)) {
        m->regs.SR &= ~(v & (STM32_FLASH_SR_ERRORS | STM32_FLASH_SR_EOP));
    } else if (off == OFF(ACR)) {
        if ((v & STM32_FLASH_ACR_DCRST) && (m->regs.ACR & STM32_FLASH_ACR_DCEN) &&
            (v & STM32_FLASH_ACR_DCEN)) {
            violation(m, "DCRST with the data cache enabled");
        } else if ((v & STM32_FLASH_ACR_DCRST) && !(v & STM32_FLASH_ACR_DCEN)) {
            m->dcache_resets++;
        }
        m->regs.ACR = v;
    } else {
        *reg_at(&m->regs, off) = v;
    }
}

static void mem_write(reg_model_t *rm, size_t off, uint32_t value, unsigned bytes)
{
    flash_model_t *m = (flash_model_t *)rm;
    uint32_t cr = m->regs.CR;
    if ((cr & STM32_FLASH_CR_LOCK) || !(cr & STM32_FLASH_CR_PG)) {
        m->regs.SR |= STM32_FLASH_SR_PGSERR;
        return;
    }
    if (m->regs.SR & STM32_FLASH_SR_BSY) {
        violation(m, "store while BSY");
    }
    uint32_t psize = (cr & STM32_FLASH_CR_PSIZE_MASK) >> STM32_FLASH_CR_PSIZE_POS;
    if (bytes != (1u << psize)) {
        m->regs.SR |= STM32_FLASH_SR_PGPERR;
        return;
    }
    if (off % bytes != 0u) {
        m->regs.SR |= STM32_FLASH_SR_PGAERR;
        return;
    }
    if (m->wrp_sectors & (1u << (off / FLASH_MODEL_SECTOR_BYTES))) {
        m->regs.SR |= STM32_FLASH_SR_WRPERR;
        return;
    }
    m->programs++;
    if (m->inject_program_error) {
        m->regs.SR |= m->inject_program_error;
        m->inject_program_error = 0u;
        return;
    }
    for (unsigned i = 0; i < bytes; i++) {
        m->mem[off + i] &= (uint8_t)(value >> (8u * i));
    }
    m->regs.SR |= STM32_FLASH_SR_BSY;
    m->busy_left = m->program_busy_reads;
}

void flash_model_init(flash_model_t *m)
{
    memset(m, 0, sizeof *m);
    m->rm.name = "FLASH";
    m->rm.base = &m->regs;
    m->rm.size = sizeof m->regs;
    m->rm.read = read_reg;
    m->rm.write = write_reg;
    m->rm.mem = m->mem;
    m->rm.mem_size = sizeof m->mem;
    m->rm.mem_write = mem_write;
    m->regs.CR = CR_RESET;
    m->erase_busy_reads = 50u;
    m->program_busy_reads = 2u;
    memset(m->mem, 0xFF, sizeof m->mem);
    reg_model_add(&m->rm);
}

void flash_model_fill(flash_model_t *m, uint32_t sector, uint8_t value)
{
    memset(&m->mem[sector * FLASH_MODEL_SECTOR_BYTES], value, FLASH_MODEL_SECTOR_BYTES);
}
