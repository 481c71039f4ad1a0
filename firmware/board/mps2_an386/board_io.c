#include "board_io.h"

#include "semihost.h"

void board_print_u32(const char *text, uint32_t value)
{
    char digits[12];
    int n = 0;
    do {
        digits[n++] = (char)('0' + value % 10u);
        value /= 10u;
    } while (value != 0u);
    char line[16];
    int k = 0;
    while (n > 0) {
        line[k++] = digits[--n];
    }
    line[k++] = '\n';
    line[k] = '\0';
    sh_puts(text);
    sh_puts(line);
}
