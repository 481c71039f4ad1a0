/* hal_replay: see hal_replay.h (host only). */
#include "hal_replay.h"

#include <stdio.h>
#include <stdlib.h>
#include <sys/stat.h>

#include "hd_rawstream.h"

struct hal_replay {
    FILE *f;
    hd_raw_reader_t reader;
};

static long file_read(void *ctx, void *buf, size_t len)
{
    FILE *f = ctx;
    size_t got = fread(buf, 1, len, f);
    return (got < len && ferror(f)) ? -1 : (long)got;
}

static hal_replay_t *fail(hal_replay_t *r, char *err, size_t errlen, const char *path,
                          const char *why)
{
    if (err != NULL && errlen > 0u) {
        snprintf(err, errlen, "%s: %s", path, why);
    }
    if (r != NULL) {
        if (r->f != NULL) {
            fclose(r->f);
        }
        free(r);
    }
    return NULL;
}

hal_replay_t *hal_replay_open(const char *path, char *err, size_t errlen)
{
    hal_replay_t *r = calloc(1, sizeof *r);
    if (r == NULL) {
        return fail(NULL, err, errlen, path, "out of memory");
    }
    struct stat st;
    if (stat(path, &st) != 0) {
        return fail(r, err, errlen, path, "cannot open");
    }
    if (!S_ISREG(st.st_mode)) {
        return fail(r, err, errlen, path, "not a regular file");
    }
    r->f = fopen(path, "rb");
    if (r->f == NULL) {
        return fail(r, err, errlen, path, "cannot open");
    }
    if (hd_raw_reader_open(&r->reader, file_read, r->f, (uint64_t)st.st_size) != HAL_OK) {
        return fail(r, err, errlen, path, r->reader.why);
    }
    return r;
}

void hal_replay_bind(hal_replay_t *r, hal_t *hal)
{
    hd_raw_reader_bind(&r->reader, hal);
}

uint32_t hal_replay_ts_us(const hal_replay_t *r)
{
    return r->reader.ts_us;
}

uint64_t hal_replay_record_count(const hal_replay_t *r)
{
    return r->reader.records;
}

uint64_t hal_replay_position(const hal_replay_t *r)
{
    return r->reader.pos;
}

uint32_t hal_replay_trailing_bytes(const hal_replay_t *r)
{
    return r->reader.trailing;
}

void hal_replay_close(hal_replay_t *r)
{
    if (r != NULL) {
        fclose(r->f);
        free(r);
    }
}
