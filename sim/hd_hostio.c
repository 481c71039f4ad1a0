/* Host file input/output with whole-or-nothing outputs.  See hd_hostio.h. */
#define _POSIX_C_SOURCE 200809L

#include "hd_hostio.h"

#include <errno.h>
#include <fcntl.h>
#include <signal.h>
#include <stdarg.h>
#include <stdlib.h>
#include <string.h>
#include <sys/stat.h>
#include <sys/types.h>
#include <unistd.h>

#ifndef HD_VERSION_STRING
#define HD_VERSION_STRING "unknown"
#endif
#ifndef HD_GIT_HASH
#define HD_GIT_HASH ""
#endif

static void fail(char *err, size_t len, const char *fmt, ...)
{
    if (err == NULL || len == 0u) {
        return;
    }
    va_list ap;
    va_start(ap, fmt);
    vsnprintf(err, len, fmt, ap);
    va_end(ap);
}

static const char *kind_of(mode_t m)
{
    if (S_ISDIR(m)) {
        return "is a directory";
    }
    if (S_ISFIFO(m)) {
        return "is a FIFO (named pipe), not a regular file";
    }
    if (S_ISCHR(m) || S_ISBLK(m)) {
        return "is a device, not a regular file";
    }
    if (S_ISSOCK(m)) {
        return "is a socket, not a regular file";
    }
    return "is not a regular file";
}

/* Opens for reading without blocking (a FIFO with no writer would block in
 * open), and checks the type; returns the descriptor in blocking mode. */
static int open_regular(const char *path, struct stat *st, char *err, size_t err_len)
{
    int fd = open(path, O_RDONLY | O_NONBLOCK | O_CLOEXEC);
    if (fd < 0) {
        fail(err, err_len, "%s: cannot open: %s", path, strerror(errno));
        return -1;
    }
    if (fstat(fd, st) != 0) {
        fail(err, err_len, "%s: cannot stat: %s", path, strerror(errno));
        close(fd);
        return -1;
    }
    if (!S_ISREG(st->st_mode)) {
        fail(err, err_len, "%s: %s", path, kind_of(st->st_mode));
        close(fd);
        return -1;
    }
    int fl = fcntl(fd, F_GETFL);
    if (fl < 0 || fcntl(fd, F_SETFL, fl & ~O_NONBLOCK) != 0) {
        fail(err, err_len, "%s: cannot read: %s", path, strerror(errno));
        close(fd);
        return -1;
    }
    return fd;
}

int hd_hostio_check_regular(const char *path, char *err, size_t err_len)
{
    struct stat st;
    int fd = open_regular(path, &st, err, err_len);
    if (fd < 0) {
        return -1;
    }
    close(fd);
    return 0;
}

char *hd_hostio_read_file(const char *path, size_t max_bytes, size_t *len, char *err,
                          size_t err_len)
{
    struct stat st;
    int fd = open_regular(path, &st, err, err_len);
    if (fd < 0) {
        return NULL;
    }
    if (st.st_size < 0 || (unsigned long long)st.st_size > (unsigned long long)max_bytes) {
        fail(err, err_len, "%s: %lld bytes, more than the limit of %zu", path,
             (long long)st.st_size, max_bytes);
        close(fd);
        return NULL;
    }
    /* The file may change while it is read: read at most max_bytes + 1. */
    char *buf = malloc(max_bytes + 2u);
    if (buf == NULL) {
        fail(err, err_len, "%s: out of memory", path);
        close(fd);
        return NULL;
    }
    size_t n = 0;
    while (n <= max_bytes) {
        ssize_t got = read(fd, buf + n, max_bytes + 1u - n);
        if (got < 0) {
            if (errno == EINTR) {
                continue;
            }
            fail(err, err_len, "%s: read error: %s", path, strerror(errno));
            free(buf);
            close(fd);
            return NULL;
        }
        if (got == 0) {
            break;
        }
        n += (size_t)got;
    }
    close(fd);
    if (n > max_bytes) {
        fail(err, err_len, "%s: more than the limit of %zu bytes", path, max_bytes);
        free(buf);
        return NULL;
    }
    buf[n] = '\0';
    *len = n;
    return buf;
}

/* ------------------------------------------------------------------ output */

static char *dup_str(const char *s)
{
    size_t n = strlen(s) + 1u;
    char *d = malloc(n);
    if (d != NULL) {
        memcpy(d, s, n);
    }
    return d;
}

static void out_free(hd_out_t *o)
{
    free(o->path);
    free(o->tmp);
    o->path = NULL;
    o->tmp = NULL;
    o->f = NULL;
}

/* Directory part of path ("." if none), heap. */
static char *dir_of(const char *path)
{
    const char *slash = strrchr(path, '/');
    if (slash == NULL) {
        return dup_str(".");
    }
    if (slash == path) {
        return dup_str("/");
    }
    size_t n = (size_t)(slash - path);
    char *d = malloc(n + 1u);
    if (d != NULL) {
        memcpy(d, path, n);
        d[n] = '\0';
    }
    return d;
}

static int open_temp(hd_out_t *o, const char *path, const struct stat *existing, char *err,
                     size_t err_len)
{
    const char *slash = strrchr(path, '/');
    const char *base = slash != NULL ? slash + 1 : path;
    size_t dlen = slash != NULL ? (size_t)(slash - path) + 1u : 0u;
    size_t cap = dlen + 1u + strlen(base) + sizeof ".tmpXXXXXX";
    o->tmp = malloc(cap);
    if (o->tmp == NULL) {
        fail(err, err_len, "%s: out of memory", path);
        return -1;
    }
    snprintf(o->tmp, cap, "%.*s.%s.tmpXXXXXX", (int)dlen, path, base);
    int fd = mkstemp(o->tmp);
    if (fd < 0) {
        fail(err, err_len, "%s: cannot write: %s", path, strerror(errno));
        return -1;
    }
    /* mkstemp makes 0600; give the file the mode a plain fopen would
     * (or keep the mode of the file it replaces). */
    mode_t mode;
    if (existing != NULL) {
        mode = existing->st_mode & 07777;
    } else {
        mode_t mask = umask(0);
        umask(mask);
        mode = 0666 & ~mask;
    }
    if (fchmod(fd, mode) != 0 || (o->f = fdopen(fd, "w")) == NULL) {
        fail(err, err_len, "%s: cannot write: %s", path, strerror(errno));
        close(fd);
        unlink(o->tmp);
        return -1;
    }
    return 0;
}

int hd_out_open(hd_out_t *o, const char *path, bool sync, char *err, size_t err_len)
{
    memset(o, 0, sizeof *o);
    o->sync = sync;
    if (strcmp(path, "-") == 0) {
        o->is_stdout = true;
        o->f = stdout;
        o->path = dup_str("(stdout)");
        return o->path != NULL ? 0 : -1;
    }
    o->path = dup_str(path);
    if (o->path == NULL) {
        fail(err, err_len, "%s: out of memory", path);
        return -1;
    }
    struct stat st;
    const bool exists = stat(path, &st) == 0;
    if (exists && S_ISDIR(st.st_mode)) {
        fail(err, err_len, "%s: cannot write: is a directory", path);
        out_free(o);
        return -1;
    }
    if (exists && !S_ISREG(st.st_mode)) {
        /* A device or FIFO: no temporary file possible, write in place. */
        o->f = fopen(path, "w");
        if (o->f == NULL) {
            fail(err, err_len, "%s: cannot write: %s", path, strerror(errno));
            out_free(o);
            return -1;
        }
        return 0;
    }
    if (open_temp(o, path, exists ? &st : NULL, err, err_len) != 0) {
        out_free(o);
        return -1;
    }
    return 0;
}

static void note_errno(hd_out_t *o)
{
    if (o->first_errno == 0) {
        o->first_errno = errno != 0 ? errno : EIO;
    }
}

int hd_out_printf(hd_out_t *o, const char *fmt, ...)
{
    va_list ap;
    va_start(ap, fmt);
    errno = 0;
    int rc = vfprintf(o->f, fmt, ap);
    va_end(ap);
    if (rc < 0) {
        note_errno(o);
        return -1;
    }
    return 0;
}

int hd_out_write(hd_out_t *o, const void *data, size_t len)
{
    errno = 0;
    if (fwrite(data, 1, len, o->f) != len) {
        note_errno(o);
        return -1;
    }
    return 0;
}

bool hd_out_failed(const hd_out_t *o)
{
    return o->first_errno != 0 || (o->f != NULL && ferror(o->f) != 0);
}

static int sync_dir(const char *path)
{
    char *dir = dir_of(path);
    if (dir == NULL) {
        return -1;
    }
    int fd = open(dir, O_RDONLY | O_CLOEXEC);
    free(dir);
    if (fd < 0) {
        return -1;
    }
    int rc = fsync(fd);
    /* Some file systems cannot sync a directory: that is not a lost write. */
    if (rc != 0 && (errno == EINVAL || errno == EROFS)) {
        rc = 0;
    }
    close(fd);
    return rc;
}

/* Phase 1: everything that can fail for lack of space (flush, fsync, close). */
static int out_finish(hd_out_t *o, char *err, size_t err_len)
{
    if (o->f == NULL) {
        fail(err, err_len, "%s: output not open", o->path != NULL ? o->path : "?");
        return -1;
    }
    int e = 0;
    errno = 0;
    if (fflush(o->f) != 0 || ferror(o->f) != 0 || o->first_errno != 0) {
        e = o->first_errno != 0 ? o->first_errno : (errno != 0 ? errno : EIO);
    }
    if (e == 0 && o->tmp != NULL && o->sync && fsync(fileno(o->f)) != 0) {
        e = errno;
    }
    if (!o->is_stdout) {
        if (fclose(o->f) != 0 && e == 0) {
            e = errno;
        }
    }
    o->f = NULL;
    if (e != 0) {
        fail(err, err_len, "%s: write failed: %s", o->path, strerror(e));
        return -1;
    }
    return 0;
}

/* Phase 2: the rename (and the directory sync). */
static int out_publish(hd_out_t *o, char *err, size_t err_len)
{
    if (o->tmp == NULL) {
        return 0;
    }
    if (rename(o->tmp, o->path) != 0) {
        fail(err, err_len, "%s: cannot replace: %s", o->path, strerror(errno));
        return -1;
    }
    free(o->tmp);
    o->tmp = NULL;
    if (o->sync && sync_dir(o->path) != 0) {
        fail(err, err_len, "%s: renamed but not synced: %s", o->path, strerror(errno));
        return -1;
    }
    return 0;
}

int hd_out_commit_all(hd_out_t *const *outs, size_t n, char *err, size_t err_len)
{
    int rc = 0;
    for (size_t i = 0; i < n && rc == 0; i++) {
        if (outs[i] != NULL && outs[i]->path != NULL) {
            rc = out_finish(outs[i], err, err_len);
        }
    }
    for (size_t i = 0; i < n && rc == 0; i++) {
        if (outs[i] != NULL && outs[i]->path != NULL) {
            rc = out_publish(outs[i], err, err_len);
        }
    }
    for (size_t i = 0; i < n; i++) {
        if (outs[i] != NULL) {
            hd_out_abort(outs[i]); /* frees; removes what was not renamed */
        }
    }
    return rc;
}

int hd_out_commit(hd_out_t *o, char *err, size_t err_len)
{
    hd_out_t *one[1] = {o};
    return hd_out_commit_all(one, 1u, err, err_len);
}

void hd_out_abort(hd_out_t *o)
{
    if (o->f != NULL && !o->is_stdout) {
        fclose(o->f);
    }
    if (o->tmp != NULL) {
        unlink(o->tmp);
    }
    out_free(o);
}

int hd_hostio_write_atomic(const char *path, const void *data, size_t len, char *err,
                           size_t err_len)
{
    hd_out_t o;
    if (hd_out_open(&o, path, true, err, err_len) != 0) {
        return -1;
    }
    if (hd_out_write(&o, data, len) != 0) {
        fail(err, err_len, "%s: write failed: %s", path, strerror(o.first_errno));
        hd_out_abort(&o);
        return -1;
    }
    return hd_out_commit(&o, err, err_len);
}

static volatile sig_atomic_t g_signal;

static void on_signal(int signo)
{
    if (g_signal == 0) {
        g_signal = signo;
    }
}

void hd_hostio_catch_signals(void)
{
    struct sigaction sa;
    memset(&sa, 0, sizeof sa);
    sa.sa_handler = on_signal;
    sigemptyset(&sa.sa_mask);
    sa.sa_flags = 0; /* no SA_RESTART: a sleep returns EINTR at once */
    sigaction(SIGINT, &sa, NULL);
    sigaction(SIGTERM, &sa, NULL);
    signal(SIGXFSZ, SIG_IGN);
}

int hd_hostio_signal(void)
{
    return (int)g_signal;
}

const char *hd_hostio_version(void)
{
    return HD_GIT_HASH[0] != '\0' ? HD_VERSION_STRING " (git " HD_GIT_HASH ")"
                                  : HD_VERSION_STRING;
}
