/* hal_semihost: see hal_semihost.h. */
#include "hal_semihost.h"

#include <string.h>

#include "hal_mock.h"
#include "hd_rawstream.h"
#include "semihost.h"

static long sh_source(void *ctx, void *buf, size_t len)
{
    const hal_sh_stream_t *s = ctx;
    return sh_read(s->fd, buf, len);
}

int hal_sh_stream_open(hal_sh_stream_t *s, const char *path)
{
    memset(s, 0, sizeof *s);
    s->reader.why = "cannot open";
    s->fd = sh_open(path, SH_MODE_RB);
    if (s->fd < 0) {
        return HAL_ERR_IO;
    }
    long size = sh_flen(s->fd);
    int rc = size < 0 ? HAL_ERR_IO
                      : hd_raw_reader_open(&s->reader, sh_source, s, (uint64_t)size);
    if (rc != HAL_OK) {
        (void)sh_close(s->fd);
        s->fd = -1;
    }
    return rc;
}

void hal_sh_stream_bind(hal_sh_stream_t *s, hal_t *hal)
{
    hd_raw_reader_bind(&s->reader, hal);
}

void hal_sh_stream_close(hal_sh_stream_t *s)
{
    if (s->fd >= 0) {
        (void)sh_close(s->fd);
        s->fd = -1;
    }
}

int hal_sh_writer_open(hal_sh_writer_t *w, const char *path)
{
    memset(w, 0, sizeof *w);
    w->fd = sh_open(path, SH_MODE_WB);
    return w->fd >= 0 ? HAL_OK : HAL_ERR_IO;
}

int hal_sh_writer_append(hal_sh_writer_t *w, const void *data, size_t len)
{
    if (len > HAL_SH_WRITER_BUF - w->len) {
        w->dropped_bytes += (uint32_t)len;
        return HAL_ERR_BUSY;
    }
    memcpy(&w->buf[w->len], data, len);
    w->len += (uint32_t)len;
    return HAL_OK;
}

int hal_sh_writer_flush(hal_sh_writer_t *w)
{
    int rc = HAL_OK;
    if (w->len > 0u && (w->fd < 0 || sh_write(w->fd, w->buf, w->len) != 0)) {
        w->io_errors++;
        rc = HAL_ERR_IO;
    }
    w->len = 0;
    return rc;
}

int hal_sh_writer_close(hal_sh_writer_t *w)
{
    int rc = hal_sh_writer_flush(w);
    if (w->fd >= 0) {
        (void)sh_close(w->fd);
        w->fd = -1;
    }
    return rc;
}

void hal_sh_canlog_hook(void *ctx, const hal_can_frame_t *frame, uint64_t t_us)
{
    char line[200];
    int n = hal_candump_format(frame, t_us, "vcan0", line, sizeof line);
    if (n > 0) {
        (void)hal_sh_writer_append(ctx, line, (size_t)n);
    }
}
