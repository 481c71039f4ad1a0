/*
 * stm32f4_system: what survives a reset and what causes one.
 *
 * - Reset cause from RCC_CSR (read once at boot, then cleared with RMVF),
 *   as hal.h's HAL_RESET_* bits.  The NRST pin is driven low by every
 *   internal reset too, so PINRSTF is set after a watchdog or software
 *   reset as well: "pin" is reported only when no other cause is.
 * - HardFault record: the fault handler stores the stacked PC, LR, xPSR and
 *   the fault status registers (CFSR, HFSR, MMFAR, BFAR) in a RAM section the
 *   startup code does not clear (.noinit), then resets.  At the next boot it
 *   is taken (checked by a magic word and a check word, then erased), so a
 *   record is reported once, and RAM garbage after power-on is not one.
 * - IWDG: the independent watchdog on the LSI oscillator (17..47 kHz per
 *   the datasheet); started once, it cannot be stopped.
 * - Reboot: SCB_AIRCR.SYSRESETREQ.
 */
#ifndef STM32F4_SYSTEM_H
#define STM32F4_SYSTEM_H

#include <stdbool.h>
#include <stdint.h>

#include "hal.h"
#include "stm32f4_regs.h"

#ifdef __cplusplus
extern "C" {
#endif

/* Classifies RCC_CSR's flags as HAL_RESET_* bits (pure):
 *   PORRSTF -> POWER_ON; BORRSTF without PORRSTF -> BROWNOUT (a power-on
 *   sets both); IWDGRSTF/WWDGRSTF -> WATCHDOG; SFTRSTF -> SOFTWARE (the
 *   REBOOT command, and the reset after a HardFault, which leaves a fault
 *   record); PINRSTF -> PIN only when nothing else is set. */
uint32_t stm32_reset_cause_from_csr(uint32_t csr);

/* Reads and clears the reset flags; returns HAL_RESET_* bits. */
uint32_t stm32_reset_cause(stm32_rcc_t *rcc);

#define STM32_FAULT_MAGIC 0x48444654u /* "HDFT" */

typedef struct {
    uint32_t magic;
    uint32_t pc, lr, xpsr;       /* stacked by the exception entry */
    uint32_t sp;                 /* stack pointer at the fault (frame address) */
    uint32_t cfsr, hfsr, mmfar, bfar;
    uint32_t check;              /* ~(sum of the words above) */
} stm32_fault_record_t;

/* Fills rec from an exception frame (r0, r1, r2, r3, r12, lr, pc, xpsr) and
 * the fault status registers; MMFAR/BFAR only when CFSR marks them valid. */
void stm32_fault_record_save(stm32_fault_record_t *rec, const uint32_t *frame, uint32_t cfsr,
                             uint32_t hfsr, uint32_t mmfar, uint32_t bfar);

/* If rec holds a valid record: copies it to *out, erases rec, returns true. */
bool stm32_fault_record_take(stm32_fault_record_t *rec, stm32_fault_record_t *out);

/* Starts the IWDG with prescaler code pr (0: /4 .. 6: /256) and reload
 * 0..4095; waits at most polls reads for the registers to update.  Returns
 * 0, HAL_ERR_RANGE or HAL_ERR_IO (update flags stuck). */
int stm32_iwdg_start(stm32_iwdg_t *iwdg, uint32_t pr, uint32_t reload, uint32_t polls);
void stm32_iwdg_reload(stm32_iwdg_t *iwdg);

/* Requests a system reset; does not return on the MCU. */
void stm32_reboot(void);

#ifdef __cplusplus
}
#endif

#endif /* STM32F4_SYSTEM_H */
