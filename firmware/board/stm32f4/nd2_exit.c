/* The end of a QEMU netduinoplus2 image (hd_nd2, hd_stm32f4_bench): a
 * fault or the return of main ends the emulation with an exit status over
 * semihosting (the board images reset instead, main_hw.c). */
#include "board.h"
#include "semihost.h"
#include "stm32f4_startup.h"

_Noreturn void board_fault(const stm32_fault_record_t *rec)
{
    (void)rec;
    sh_puts("board: fault exception\n");
    sh_exit(BOARD_EXIT_FAULT);
}

_Noreturn void board_exit(int status)
{
    sh_exit(status);
}
