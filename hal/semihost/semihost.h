/*
 * semihost: ARM semihosting calls (`bkpt 0xab`, r0 = operation, r1 = argument
 * block), the channel a debugger or QEMU gives a bare-metal image to the host's
 * files.  No newlib: these are the raw calls.
 *
 * QEMU: -semihosting-config enable=on,target=native[,arg=...]
 * On a real board without a debugger attached a BKPT instruction faults:
 * semihosting is for the emulated board and bench tests only.
 */
#ifndef SEMIHOST_H
#define SEMIHOST_H

#include <stddef.h>
#include <stdint.h>

#ifdef __cplusplus
extern "C" {
#endif

/* SYS_OPEN modes (ISO C fopen equivalents). */
#define SH_MODE_RB 1  /* "rb" */
#define SH_MODE_WB 5  /* "wb" */

/* Opens a host file; returns a handle >= 0 or -1. */
int sh_open(const char *path, int mode);
int sh_close(int fd);
/* Reads up to len bytes; returns the number read (0 at end of file) or -1. */
long sh_read(int fd, void *buf, size_t len);
/* Writes all len bytes; returns 0 or -1. */
int sh_write(int fd, const void *buf, size_t len);
/* Length of an open file in bytes, or -1. */
long sh_flen(int fd);
/* Writes a NUL-terminated string to the host's console (stderr of QEMU). */
void sh_puts(const char *s);
/* Copies the command line (QEMU: the arg= values joined by spaces) into buf,
 * NUL terminated; returns its length or -1. */
int sh_cmdline(char *buf, size_t cap);
/* Ends the emulation with this exit status (SYS_EXIT_EXTENDED,
 * ADP_Stopped_ApplicationExit).  Does not return. */
_Noreturn void sh_exit(int status);

#ifdef __cplusplus
}
#endif

#endif /* SEMIHOST_H */
