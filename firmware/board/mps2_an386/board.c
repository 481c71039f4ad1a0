/* Board support for mps2-an386: SysTick, command line, markers, and the
 * few libc functions the firmware and the compiler use (the image links no
 * libc, so no heap can be pulled in). */
#include "board.h"

#include "semihost.h"

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

static char g_cmdline[512];

int board_args(char **argv, int max)
{
    if (sh_cmdline(g_cmdline, sizeof g_cmdline) < 0) {
        return -1;
    }
    int n = 0;
    char *p = g_cmdline;
    while (*p != '\0' && n < max) {
        while (*p == ' ') {
            *p++ = '\0';
        }
        if (*p == '\0') {
            break;
        }
        argv[n++] = p;
        while (*p != '\0' && *p != ' ') {
            p++;
        }
    }
    return n;
}

/* Markers: one `bx lr` each, at distinct addresses (see board.h). */
__asm__(".section .text.hd_mark,\"ax\",%progbits\n"
        ".balign 4\n"
        ".global hd_mark_begin\n.type hd_mark_begin,%function\n.thumb_func\n"
        "hd_mark_begin: bx lr\n.size hd_mark_begin,.-hd_mark_begin\n"
        ".global hd_mark_end\n.type hd_mark_end,%function\n.thumb_func\n"
        "hd_mark_end: bx lr\n.size hd_mark_end,.-hd_mark_end\n"
        ".global hd_mark_section\n.type hd_mark_section,%function\n.thumb_func\n"
        "hd_mark_section: bx lr\n.size hd_mark_section,.-hd_mark_section\n"
        ".global hd_bench_loop\n.type hd_bench_loop,%function\n.thumb_func\n"
        "hd_bench_loop: subs r0, r0, #1\n bne hd_bench_loop\n bx lr\n"
        ".size hd_bench_loop,.-hd_bench_loop\n"
        ".text\n");
