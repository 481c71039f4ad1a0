/*
 * hd_hostio: file input and output for the host programs (hdsim,
 * hdsim-campaign, hdjoint-host).  Host only (POSIX, heap).
 *
 * Input: a whole file read into memory, with a size limit, refusing what is
 * not a regular file (a directory, a FIFO that would block, /dev/zero that
 * never ends) with one message.
 *
 * Output: a file is written under a temporary name in its own directory and
 * renamed over the target only when it is complete (hd_out_commit), so a
 * reader never sees a file that is half old and half new; if anything fails
 * the temporary file is removed and the old file stays as it was.  A target
 * that exists and is not a regular file (/dev/null, /dev/full, a FIFO, a
 * terminal) and "-" (stdout) are written directly; every write is still
 * checked.
 *
 * Every function reports failure as -1 with "PATH: what: strerror" in err.
 */
#ifndef HD_HOSTIO_H
#define HD_HOSTIO_H

#include <stdbool.h>
#include <stddef.h>
#include <stdio.h>

#ifdef __cplusplus
extern "C" {
#endif

/* Exit status of the host programs, the same in every one (docs/results/reliability.md,
 * "Exit status"): 0 ok, 128 + signal when interrupted, and: */
#define EXIT_RUN 1   /* the run failed (hdjoint-host: SocketCAN, --cmd frames not handled) */
#define EXIT_USAGE 2 /* bad command line or bad input */
#define EXIT_WRITE 3 /* an output could not be written (the old files stay) */

/* Limit for text inputs (scenario, configuration): far above any real one. */
#define HD_HOSTIO_TEXT_MAX_BYTES (1u << 20)

/* Reads the regular file at path (at most max_bytes) into a heap buffer with
 * a NUL after the last byte (embedded NULs are kept: check them with len).
 * Returns NULL with a message in err; the caller frees the buffer. */
char *hd_hostio_read_file(const char *path, size_t max_bytes, size_t *len, char *err,
                          size_t err_len);

/* 0 if path names a regular file that can be opened (without blocking),
 * else -1 with the reason ("is a directory", "is a FIFO, not a file", ...). */
int hd_hostio_check_regular(const char *path, char *err, size_t err_len);

typedef struct {
    FILE *f;          /* write here (stdio); NULL when not open */
    char *path;       /* the target */
    char *tmp;        /* temporary name, NULL when written directly */
    bool is_stdout;
    bool sync;        /* fsync before the rename (and the directory after) */
    int first_errno;  /* errno of the first failed write (0: none) */
} hd_out_t;

/* Opens an output ("-" = stdout).  sync asks for fsync of the file and its
 * directory at commit. */
int hd_out_open(hd_out_t *o, const char *path, bool sync, char *err, size_t err_len);

/* Checked writes: -1 on failure (errno kept for the commit's message). */
int hd_out_printf(hd_out_t *o, const char *fmt, ...)
#if defined(__GNUC__)
    __attribute__((format(printf, 2, 3)))
#endif
    ;
int hd_out_write(hd_out_t *o, const void *data, size_t len);

/* true if a write to o->f has failed so far. */
bool hd_out_failed(const hd_out_t *o);

/* Flushes, (fsyncs,) closes and renames the temporary file over the target.
 * On any failure: the temporary file is removed, -1 with a message. */
int hd_out_commit(hd_out_t *o, char *err, size_t err_len);

/* The same for several outputs: all are flushed and closed first, and only
 * if that worked for every one are they renamed, so a full disk never
 * leaves a new file next to an old one.  NULL entries and outputs that were
 * never opened are skipped.  Every output is released afterwards. */
int hd_out_commit_all(hd_out_t *const *outs, size_t n, char *err, size_t err_len);

/* Closes and removes the temporary file; the target is untouched.  Safe to
 * call on an output that was never opened or already committed. */
void hd_out_abort(hd_out_t *o);

/* Writes a whole file atomically: temporary file, write, fsync, rename,
 * fsync of the directory.  For small state files (the NVM image). */
int hd_hostio_write_atomic(const char *path, const void *data, size_t len, char *err,
                           size_t err_len);

/* Installs SIGINT/SIGTERM handlers that only record the signal (the program
 * polls hd_hostio_signal() and ends cleanly), and ignores SIGXFSZ: a file
 * size limit (ulimit -f) then fails the write with EFBIG, reported like a
 * full disk, instead of killing the program. */
void hd_hostio_catch_signals(void);

/* 0, or the number of the first SIGINT/SIGTERM received. */
int hd_hostio_signal(void);

/* "VERSION (git HASH)" of this build, for --version. */
const char *hd_hostio_version(void);

#ifdef __cplusplus
}
#endif

#endif /* HD_HOSTIO_H */
