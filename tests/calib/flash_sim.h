/* An in-memory flash for the record store tests: erase sets 0xFF; every
 * erased or written byte costs one unit of `budget`; when it runs out the
 * "power fails" and nothing more is stored (the call reports an error, as a
 * browned-out MCU would never return at all).  Header-only, test code. */
#ifndef FLASH_SIM_H
#define FLASH_SIM_H

#include <string.h>

#include "hd_record_store.h"

#define FLASH_SIM_BYTES 4096u

typedef struct {
    uint8_t mem[FLASH_SIM_BYTES];
    long budget;   /* < 0: unlimited */
    int fail_read;
    int fail_write;
    uint8_t work[HD_STORE_IMAGE_MAX];
} flash_sim_t;

static int flash_sim_read(void *ctx, size_t off, void *buf, size_t len)
{
    flash_sim_t *f = (flash_sim_t *)ctx;
    if (f->fail_read || off + len > FLASH_SIM_BYTES) {
        return -1;
    }
    memcpy(buf, f->mem + off, len);
    return 0;
}

static int flash_sim_spend(flash_sim_t *f)
{
    if (f->budget < 0) {
        return 1;
    }
    if (f->budget == 0) {
        return 0;
    }
    f->budget--;
    return 1;
}

static int flash_sim_write(void *ctx, size_t off, const void *buf, size_t len)
{
    flash_sim_t *f = (flash_sim_t *)ctx;
    if (f->fail_write || off + len > FLASH_SIM_BYTES) {
        return -1;
    }
    for (size_t i = 0; i < len; ++i) {
        if (!flash_sim_spend(f)) {
            return -1;
        }
        f->mem[off + i] = ((const uint8_t *)buf)[i];
    }
    return 0;
}

static int flash_sim_erase(void *ctx, size_t off, size_t len)
{
    flash_sim_t *f = (flash_sim_t *)ctx;
    if (off + len > FLASH_SIM_BYTES) {
        return -1;
    }
    for (size_t i = 0; i < len; ++i) {
        if (!flash_sim_spend(f)) {
            return -1;
        }
        f->mem[off + i] = 0xFFu;
    }
    return 0;
}

static inline hd_store_io_t flash_sim_reset(flash_sim_t *f)
{
    memset(f->mem, 0xFF, sizeof f->mem);
    f->budget = -1;
    f->fail_read = 0;
    f->fail_write = 0;
    hd_store_io_t io = {f, FLASH_SIM_BYTES, flash_sim_read, flash_sim_write, flash_sim_erase,
                        f->work, sizeof f->work};
    return io;
}

#endif /* FLASH_SIM_H */
