/*
 * Startup for mps2-an386: vector table, reset handler (FPU on, .data copied,
 * .bss zeroed, then main), and fault handlers that report and exit.
 */
#include <stdint.h>

#include "board.h"
#include "semihost.h"

extern uint32_t _sidata, _sdata, _edata, _sbss, _ebss, _estack;
int main(void);
void Reset_Handler(void);
void HardFault_Handler(void);
void Default_Handler(void);

#define SCB_CPACR (*(volatile uint32_t *)0xE000ED88u)

/* Cortex-M4 system exceptions, then the 32 AN386 interrupts (all unused).
 * The linker places .vectors at 0x0, where the core reads SP and PC. */
__attribute__((section(".vectors"), used)) const uintptr_t g_vectors[16 + 32] = {
    [0] = (uintptr_t)&_estack,
    [1] = (uintptr_t)&Reset_Handler,
    [2] = (uintptr_t)&Default_Handler,  /* NMI */
    [3] = (uintptr_t)&HardFault_Handler,
    [4] = (uintptr_t)&HardFault_Handler, /* MemManage */
    [5] = (uintptr_t)&HardFault_Handler, /* BusFault */
    [6] = (uintptr_t)&HardFault_Handler, /* UsageFault */
    [11] = (uintptr_t)&Default_Handler, /* SVCall */
    [12] = (uintptr_t)&Default_Handler, /* DebugMon */
    [14] = (uintptr_t)&Default_Handler, /* PendSV */
    [15] = (uintptr_t)&SysTick_Handler,
    [16] = (uintptr_t)&Default_Handler, /* IRQ0; the rest are zero (never enabled) */
};

void Reset_Handler(void)
{
    /* Full access to CP10/CP11 before any floating-point instruction: an FPU
     * instruction with the FPU off is a UsageFault (QEMU models it too). */
    SCB_CPACR |= (0xFu << 20);
    __asm__ volatile("dsb\n\tisb" ::: "memory");

    const uint32_t *src = &_sidata;
    for (uint32_t *dst = &_sdata; dst < &_edata;) {
        *dst++ = *src++;
    }
    for (uint32_t *dst = &_sbss; dst < &_ebss;) {
        *dst++ = 0u;
    }
    sh_exit(main());
}

void HardFault_Handler(void)
{
    sh_puts("board: fault exception\n");
    sh_exit(BOARD_EXIT_FAULT);
}

void Default_Handler(void)
{
    sh_puts("board: unexpected exception\n");
    sh_exit(BOARD_EXIT_FAULT);
}
