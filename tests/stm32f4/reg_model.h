/*
 * reg_model: the host side of STM32_REG_HOOKS.  The drivers under test
 * (firmware/board/stm32f4, built with -DSTM32_REG_HOOKS) read and write
 * their registers through stm32_reg_read / stm32_reg_write; this file
 * routes each access to the peripheral model whose register block holds
 * the address, which then behaves as the reference manual describes
 * (handshakes, flags cleared by writing 1 or 0, counters, busy times).
 * Accesses to an address no model claims fail the test (a driver touching
 * a register it should not).
 */
#ifndef REG_MODEL_H
#define REG_MODEL_H

#include <stddef.h>
#include <stdint.h>

#include "stm32f4_regs.h"

typedef struct reg_model reg_model_t;

struct reg_model {
    const char *name;
    volatile void *base;          /* the register block the driver is given */
    size_t size;
    /* offset in bytes from base; read returns the value the driver sees */
    uint32_t (*read)(reg_model_t *m, size_t offset);
    void (*write)(reg_model_t *m, size_t offset, uint32_t value);
    /* stores into flash memory (programming); NULL: not a flash model */
    volatile uint8_t *mem;
    size_t mem_size;
    void (*mem_write)(reg_model_t *m, size_t offset, uint32_t value, unsigned bytes);
    uint32_t reads, writes;       /* accesses seen (for bounded-wait checks) */
};

/* Registers a model (at most 16 at a time); reg_model_reset forgets all. */
void reg_model_add(reg_model_t *m);
void reg_model_reset(void);

/* Accesses that hit no model since the last reset (should be 0). */
uint32_t reg_model_stray_accesses(void);

/* Register word at byte offset of a block. */
static inline stm32_reg_t *reg_at(volatile void *base, size_t offset)
{
    return (stm32_reg_t *)(void *)((volatile uint8_t *)base + offset);
}

#endif /* REG_MODEL_H */
