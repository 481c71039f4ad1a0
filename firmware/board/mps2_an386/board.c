/* Board support for mps2-an386: the semihosting command line.  SysTick is
 * in board_systick.c (a board with another tick timer supplies its own
 * board_systick_start/stop), the markers in ../common/hd_mark.c. */
#include "board.h"

#include "semihost.h"

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
