/*
 * Board support for QEMU's mps2-an386 (ARM MPS2 FPGA image AN386: a
 * Cortex-M4 with FPU, 25 MHz system clock, 4 MB SSRAM at 0x0 used as
 * "flash", 4 MB SSRAM at 0x20000000 used as RAM; the linker script limits
 * both to an STM32F4/G4 class part: 512 KB flash, 128 KB RAM).
 *
 * What a real board replaces is listed in docs/results/target.md (porting guide).
 */
#ifndef BOARD_H
#define BOARD_H

#include <stddef.h>
#include <stdint.h>

#include "hd_mark.h"

#ifdef __cplusplus
extern "C" {
#endif

/* The name in hal_t (an image of main_run.c built for another board, such
 * as the STM32F4 port's netduinoplus2 emulator image, defines its own). */
#ifndef BOARD_NAME
#define BOARD_NAME "mps2-an386"
#endif

#define BOARD_CPU_HZ 25000000u  /* SysTick clock source: the processor clock */
#define BOARD_TICK_HZ 1000u

/* Exit statuses of the images (SYS_EXIT_EXTENDED). */
#define BOARD_EXIT_OK 0
#define BOARD_EXIT_USAGE 2       /* bad command line */
#define BOARD_EXIT_IO 3          /* a host file could not be opened/written */
#define BOARD_EXIT_STREAM 4      /* the raw stream is invalid */
#define BOARD_EXIT_INIT 5        /* hd_fw_init / hd_kf_init failed */
#define BOARD_EXIT_OVERFLOW 6    /* an output buffer overflowed: data lost */
#define BOARD_EXIT_FAULT 0x7f    /* HardFault / unexpected exception */

/* The 1 kHz tick: each image defines it (vector table entry 15). */
void SysTick_Handler(void);

/* Starts SysTick at BOARD_TICK_HZ from the processor clock, interrupt on. */
void board_systick_start(void);
void board_systick_stop(void);

static inline void board_irq_disable(void)
{
    __asm__ volatile("cpsid i" ::: "memory");
}

static inline void board_irq_enable(void)
{
    __asm__ volatile("cpsie i" ::: "memory");
}

/* Sleeps until an interrupt (WFI).  Under QEMU -icount sleep=off the
 * virtual clock jumps to the next SysTick, so idle time costs nothing. */
static inline void board_wait_for_interrupt(void)
{
    __asm__ volatile("wfi" ::: "memory");
}

/* Splits the semihosting command line into at most max words (in place,
 * separated by spaces); returns the word count, or -1 if there is none. */
int board_args(char **argv, int max);


#ifdef __cplusplus
}
#endif

#endif /* BOARD_H */
