/* semihost: see semihost.h.  Cortex-M (Thumb) semihosting: BKPT 0xAB. */
#include "semihost.h"

enum {
    SYS_OPEN = 0x01,
    SYS_CLOSE = 0x02,
    SYS_WRITE0 = 0x04,
    SYS_WRITE = 0x05,
    SYS_READ = 0x06,
    SYS_FLEN = 0x0C,
    SYS_GET_CMDLINE = 0x15,
    SYS_EXIT_EXTENDED = 0x20,
};

#define ADP_STOPPED_APPLICATION_EXIT 0x20026u

/* The host reads and writes the argument block and the buffers it points
 * to: the "memory" clobber keeps the compiler from caching them. */
static int32_t sh_call(uint32_t op, const void *arg)
{
    register uint32_t r0 __asm__("r0") = op;
    register const void *r1 __asm__("r1") = arg;
    __asm__ volatile("bkpt 0xab" : "+r"(r0) : "r"(r1) : "memory");
    return (int32_t)r0;
}

static size_t str_len(const char *s)
{
    size_t n = 0;
    while (s[n] != '\0') {
        n++;
    }
    return n;
}

int sh_open(const char *path, int mode)
{
    uint32_t block[3] = {(uint32_t)(uintptr_t)path, (uint32_t)mode, (uint32_t)str_len(path)};
    return (int)sh_call(SYS_OPEN, block);
}

int sh_close(int fd)
{
    uint32_t block[1] = {(uint32_t)fd};
    return (int)sh_call(SYS_CLOSE, block);
}

long sh_read(int fd, void *buf, size_t len)
{
    uint32_t block[3] = {(uint32_t)fd, (uint32_t)(uintptr_t)buf, (uint32_t)len};
    int32_t not_read = sh_call(SYS_READ, block); /* bytes NOT read */
    if (not_read < 0 || (uint32_t)not_read > len) {
        return -1;
    }
    return (long)(len - (uint32_t)not_read);
}

int sh_write(int fd, const void *buf, size_t len)
{
    uint32_t block[3] = {(uint32_t)fd, (uint32_t)(uintptr_t)buf, (uint32_t)len};
    return sh_call(SYS_WRITE, block) == 0 ? 0 : -1; /* returns bytes NOT written */
}

long sh_flen(int fd)
{
    uint32_t block[1] = {(uint32_t)fd};
    return (long)sh_call(SYS_FLEN, block);
}

void sh_puts(const char *s)
{
    (void)sh_call(SYS_WRITE0, s);
}

int sh_cmdline(char *buf, size_t cap)
{
    uint32_t block[2] = {(uint32_t)(uintptr_t)buf, (uint32_t)cap};
    if (cap == 0u || sh_call(SYS_GET_CMDLINE, block) != 0) {
        return -1;
    }
    size_t n = block[1] < cap ? block[1] : cap - 1u;
    buf[n] = '\0';
    return (int)n;
}

_Noreturn void sh_exit(int status)
{
    uint32_t block[2] = {ADP_STOPPED_APPLICATION_EXIT, (uint32_t)status};
    for (;;) {
        (void)sh_call(SYS_EXIT_EXTENDED, block);
    }
}
