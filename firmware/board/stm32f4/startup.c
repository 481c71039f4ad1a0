/*
 * Startup for the STM32F405/F446 images (boards and the netduinoplus2
 * emulator image): vector table, reset handler (FPU on, .data copied,
 * .bss zeroed, .noinit left alone), fault handlers.
 *
 * A HardFault (or MemManage/BusFault/UsageFault, or an interrupt nobody
 * handles) stores a record in .noinit RAM (stm32f4_system.h) and calls
 * board_fault, which each image defines: the board images reset (the next
 * boot reports the record through hal_system_t.boot_info), the emulator
 * image prints it and exits.
 */
#include <stdint.h>

#include "stm32f4_regs.h"
#include "stm32f4_startup.h"
#include "stm32f4_system.h"

extern uint32_t _sidata, _sdata, _edata, _sbss, _ebss, _estack;
int main(void);
void Reset_Handler(void);
void HardFault_Handler(void);
void Default_Handler(void);
void stm32_fault_entry(uint32_t *frame);

/* Survives a reset: the linker script places .noinit first in RAM and the
 * reset handler does not touch it. */
__attribute__((section(".noinit"))) stm32_fault_record_t g_stm32_fault_record;

#define WEAK_DEFAULT __attribute__((weak, alias("Default_Handler")))
void TIM1_UP_TIM10_IRQHandler(void) WEAK_DEFAULT;
void TIM2_IRQHandler(void) WEAK_DEFAULT;
void CAN1_TX_IRQHandler(void) WEAK_DEFAULT;

/* Cortex-M4 system exceptions, then the device interrupts (97 on the F446,
 * 82 on the F405); the ones no image uses stay on Default_Handler. */
#define D_ (uintptr_t)&Default_Handler
#define D2 D_, D_
#define D4 D2, D2
#define D8 D4, D4
#define D16 D8, D8
#define D64 D16, D16, D16, D16
__attribute__((section(".vectors"), used)) const uintptr_t g_vectors[16u + STM32_IRQ_COUNT] = {
    (uintptr_t)&_estack,
    (uintptr_t)&Reset_Handler,
    D_,                                 /* NMI */
    (uintptr_t)&HardFault_Handler,
    (uintptr_t)&HardFault_Handler,      /* MemManage */
    (uintptr_t)&HardFault_Handler,      /* BusFault */
    (uintptr_t)&HardFault_Handler,      /* UsageFault */
    0u, 0u, 0u, 0u,                     /* reserved */
    D_,                                 /* SVCall */
    D_,                                 /* DebugMon */
    0u,                                 /* reserved */
    D_,                                 /* PendSV */
    D_,                                 /* SysTick: unused */
    D16, D2,                            /* IRQ 0..17 */
    D_,                                 /* 18 ADC */
    (uintptr_t)&CAN1_TX_IRQHandler,     /* 19 */
    D4, D_,                             /* 20..24 */
    (uintptr_t)&TIM1_UP_TIM10_IRQHandler, /* 25 */
    D2,                                 /* 26, 27 */
    (uintptr_t)&TIM2_IRQHandler,        /* 28 */
    D64, D4,                            /* 29..96 */
};
_Static_assert(STM32_IRQ_CAN1_TX == 19u && STM32_IRQ_TIM1_UP_TIM10 == 25u &&
                   STM32_IRQ_TIM2 == 28u && STM32_IRQ_COUNT == 97u,
               "the vector table lists the handlers at these positions");

void Reset_Handler(void)
{
    /* CP10/CP11 full access before any floating-point instruction. */
    STM32_SCB_CPACR |= (0xFu << 20);
    __asm__ volatile("dsb\n\tisb" ::: "memory");
    /* MemManage, BusFault and UsageFault get their own entry (recorded the
     * same way) instead of escalating. */
    STM32_SCB_SHCSR |= STM32_SCB_SHCSR_FAULTS_ENA;
    /* The linker-script bounds of one region each: the start-up idiom. */
    const uint32_t *src = &_sidata;
    /* cppcheck-suppress comparePointers */
    for (uint32_t *dst = &_sdata; dst < &_edata;) {
        *dst++ = *src++;
    }
    /* cppcheck-suppress comparePointers */
    for (uint32_t *dst = &_sbss; dst < &_ebss;) {
        *dst++ = 0u;
    }
    board_early_init();
    board_exit(main());
}

/* Which stack holds the exception frame: EXC_RETURN bit 2 (0 = MSP). */
__attribute__((naked)) void HardFault_Handler(void)
{
    __asm__ volatile("tst lr, #4\n\t"
                     "ite eq\n\t"
                     "mrseq r0, msp\n\t"
                     "mrsne r0, psp\n\t"
                     "b stm32_fault_entry\n");
}

void stm32_fault_entry(uint32_t *frame)
{
    stm32_fault_record_save(&g_stm32_fault_record, frame, STM32_SCB_CFSR, STM32_SCB_HFSR,
                            STM32_SCB_MMFAR, STM32_SCB_BFAR);
    board_fault(&g_stm32_fault_record);
}

/* An interrupt without a handler is a fault too (its frame is on MSP:
 * no image uses the process stack). */
__attribute__((naked)) void Default_Handler(void)
{
    __asm__ volatile("mrs r0, msp\n\t"
                     "b stm32_fault_entry\n");
}
