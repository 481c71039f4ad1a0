/*
 * What each STM32F4 image supplies to the shared startup (startup.c).
 */
#ifndef STM32F4_STARTUP_H
#define STM32F4_STARTUP_H

#include "stm32f4_system.h"

#ifdef __cplusplus
extern "C" {
#endif

/* The HardFault record of the previous run (.noinit RAM), before the board
 * takes it at boot. */
extern stm32_fault_record_t g_stm32_fault_record;

/* Runs before main (after .data/.bss): the emulator image brings up the
 * clock here, the board images do everything in main. */
void board_early_init(void);

/* A fault was recorded in *rec: the board images reset, the emulator image
 * reports and exits.  Does not return. */
_Noreturn void board_fault(const stm32_fault_record_t *rec);

/* main returned with this status: the board images reset, the emulator
 * image exits QEMU with it.  Does not return. */
_Noreturn void board_exit(int status);

#ifdef __cplusplus
}
#endif

#endif /* STM32F4_STARTUP_H */
