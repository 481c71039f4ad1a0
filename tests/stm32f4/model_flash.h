/*
 * model_flash: a register-level model of the STM32F4 flash interface
 * (RM0090 section 3) and of the flash memory behind it, for the NVM driver
 * tests: FLASH_CR locked at reset, unlocked only by KEY1 then KEY2 (any
 * other value locks it until reset), writes to a locked CR ignored; sector
 * erase (SER + SNB + STRT) keeps BSY set for `erase_busy_reads` reads of SR
 * then leaves the sector 0xFF; programming only with PG set: a store while
 * PG = 0 is PGSERR, a store whose size differs from PSIZE is PGPERR, a
 * misaligned one PGAERR, a store into a write-protected sector WRPERR; a
 * program clears bits only (new = old & value); error flags and EOP are
 * cleared by writing 1.  Faults can be injected.
 */
#ifndef MODEL_FLASH_H
#define MODEL_FLASH_H

#include <stdbool.h>
#include <stdint.h>

#include "reg_model.h"

#define FLASH_MODEL_SECTORS 2u
#define FLASH_MODEL_SECTOR_BYTES 16384u
#define FLASH_MODEL_FIRST_SNB 1u  /* the two modelled sectors are SNB 1 and 2 */

typedef struct {
    reg_model_t rm;
    stm32_flash_t regs;
    uint8_t mem[FLASH_MODEL_SECTORS * FLASH_MODEL_SECTOR_BYTES];
    uint32_t key_state;          /* 0: expect KEY1, 1: expect KEY2 */
    bool locked_until_reset;
    uint32_t busy_left;          /* SR reads until BSY clears */
    uint32_t erase_busy_reads;
    uint32_t program_busy_reads;
    bool busy_forever;           /* inject: BSY never clears */
    uint32_t wrp_sectors;        /* bit per modelled sector: write protected */
    uint32_t inject_program_error; /* SR error bit raised by the next program */
    uint32_t inject_erase_error;   /* SR error bit raised by the next erase */
    uint32_t erases, programs;
    uint32_t dcache_resets;      /* DCRST written with the data cache disabled */
    uint32_t violations;
    const char *last_violation;
} flash_model_t;

/* Reset state, memory erased (0xFF), registered with reg_model. */
void flash_model_init(flash_model_t *m);

/* Fills the memory of one modelled sector (as if programmed earlier). */
void flash_model_fill(flash_model_t *m, uint32_t sector, uint8_t value);

#endif /* MODEL_FLASH_H */
