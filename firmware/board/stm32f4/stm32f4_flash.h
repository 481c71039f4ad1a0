/*
 * stm32f4_flash: the HAL's NVM part in on-chip flash (RM0090 section 3).
 *
 * The region is a run of equal sectors reserved by the linker script (on
 * this port sectors 1 and 2, 16 KB each at 0x08004000): the firmware keeps
 * its A/B record store there, copy A in the first half, copy B in the
 * second, and a save erases exactly one half.  So:
 *   read  = a copy from the memory-mapped flash;
 *   erase = sector erase (FLASH_CR.SER + SNB + STRT), only whole sectors
 *           (offset and length multiples of the sector size), else
 *           HAL_ERR_RANGE;
 *   write = programming (FLASH_CR.PG), words (PSIZE x32, 2.7..3.6 V) where
 *           the address is word aligned, bytes (PSIZE x8) at the ends, each
 *           read back; bits can only go 1 -> 0, so a write over data that was
 *           not erased is caught by the read-back.
 * Each operation unlocks (KEYR: KEY1 then KEY2), waits for BSY to clear at
 * most `erase_polls` / `program_polls` reads, checks the error flags
 * (PGSERR, PGPERR, PGAERR, WRPERR, OPERR), clears them and locks again.  Any
 * error or timeout is HAL_ERR_IO: the firmware answers NVM_ERROR and the
 * other copy (the old record) is untouched.
 *
 * While a sector is erased the CPU stalls on every flash read (single-bank
 * flash: the tick interrupt's code is in flash too), up to the datasheet's
 * maximum sector erase time; the firmware counts the ticks it missed from
 * the board's cycle-counter clock, and the watchdog period is longer than
 * that stall.
 */
#ifndef STM32F4_FLASH_H
#define STM32F4_FLASH_H

#include <stddef.h>
#include <stdint.h>

#include "hal.h"
#include "stm32f4_regs.h"

#ifdef __cplusplus
extern "C" {
#endif

typedef struct {
    stm32_flash_t *regs;
    uint8_t *mem;             /* memory-mapped start of the region */
    uint32_t first_sector;    /* SNB of its first sector */
    uint32_t sector_count;
    uint32_t sector_bytes;    /* all sectors of the region are this size */
    uint32_t erase_polls;     /* bound on the BSY wait of one sector erase */
    uint32_t program_polls;   /* bound on the BSY wait of one program operation */
} stm32_flash_config_t;

typedef struct {
    stm32_flash_config_t cfg;
    uint32_t errors;          /* operations that ended in HAL_ERR_IO */
    uint32_t last_sr;         /* FLASH_SR error bits of the last failure (0: timeout) */
} stm32_flash_drv_t;

void stm32_flash_init(stm32_flash_drv_t *drv, const stm32_flash_config_t *cfg);

/* Points nvm at the driver (size = sector_count x sector_bytes). */
void stm32_flash_bind(stm32_flash_drv_t *drv, hal_nvm_t *nvm);

int stm32_flash_read(void *ctx, size_t offset, void *buf, size_t len);
int stm32_flash_write(void *ctx, size_t offset, const void *buf, size_t len);
int stm32_flash_erase(void *ctx, size_t offset, size_t len);

#ifdef __cplusplus
}
#endif

#endif /* STM32F4_FLASH_H */
