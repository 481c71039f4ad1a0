/* The mps2-an386 tick: SysTick from the 25 MHz processor clock (board.h). */
#include "board.h"

#define SYST_CSR (*(volatile uint32_t *)0xE000E010u)
#define SYST_RVR (*(volatile uint32_t *)0xE000E014u)
#define SYST_CVR (*(volatile uint32_t *)0xE000E018u)
#define SYST_CSR_ENABLE (1u << 0)
#define SYST_CSR_TICKINT (1u << 1)
#define SYST_CSR_CLKSOURCE (1u << 2) /* 1: processor clock */

void board_systick_start(void)
{
    SYST_CSR = 0u;
    SYST_RVR = BOARD_CPU_HZ / BOARD_TICK_HZ - 1u; /* 24999: 1 ms at 25 MHz */
    SYST_CVR = 0u;
    SYST_CSR = SYST_CSR_CLKSOURCE | SYST_CSR_TICKINT | SYST_CSR_ENABLE;
}

void board_systick_stop(void)
{
    SYST_CSR = 0u;
}
