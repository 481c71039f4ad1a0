/* Small output helpers shared by the board's images (semihosting console). */
#ifndef BOARD_IO_H
#define BOARD_IO_H

#include <stdint.h>

#ifdef __cplusplus
extern "C" {
#endif

/* Writes "text" then the decimal value then "\n" to the console. */
void board_print_u32(const char *text, uint32_t value);

/* Little-endian 32-bit store (the dump formats are little-endian). */
static inline void board_put_le32(uint8_t *p, uint32_t v)
{
    p[0] = (uint8_t)v;
    p[1] = (uint8_t)(v >> 8);
    p[2] = (uint8_t)(v >> 16);
    p[3] = (uint8_t)(v >> 24);
}

#ifdef __cplusplus
}
#endif

#endif /* BOARD_IO_H */
