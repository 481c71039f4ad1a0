/* stm32f4_flash: see stm32f4_flash.h. */
#include "stm32f4_flash.h"

void stm32_flash_init(stm32_flash_drv_t *drv, const stm32_flash_config_t *cfg)
{
    drv->cfg = *cfg;
    drv->errors = 0u;
    drv->last_sr = 0u;
}

static size_t region_size(const stm32_flash_drv_t *drv)
{
    return (size_t)drv->cfg.sector_count * drv->cfg.sector_bytes;
}

void stm32_flash_bind(stm32_flash_drv_t *drv, hal_nvm_t *nvm)
{
    nvm->ctx = drv;
    nvm->size = region_size(drv);
    nvm->read = stm32_flash_read;
    nvm->write = stm32_flash_write;
    nvm->erase = stm32_flash_erase;
}

static int in_range(const stm32_flash_drv_t *drv, size_t offset, size_t len)
{
    size_t size = region_size(drv);
    return offset <= size && len <= size - offset;
}

int stm32_flash_read(void *ctx, size_t offset, void *buf, size_t len)
{
    const stm32_flash_drv_t *drv = ctx;
    if (!in_range(drv, offset, len)) {
        return HAL_ERR_RANGE;
    }
    const volatile uint8_t *src = drv->cfg.mem + offset;
    uint8_t *dst = buf;
    for (size_t i = 0; i < len; i++) {
        dst[i] = src[i];
    }
    return HAL_OK;
}

/* Bounded wait for BSY = 0. */
static int wait_idle(stm32_flash_drv_t *drv, uint32_t polls)
{
    return stm32_wait(&drv->cfg.regs->SR, STM32_FLASH_SR_BSY, 0u, polls) ? HAL_OK : HAL_ERR_IO;
}

static int unlock(stm32_flash_drv_t *drv)
{
    stm32_flash_t *f = drv->cfg.regs;
    if ((STM32_RD(f->CR) & STM32_FLASH_CR_LOCK) != 0u) {
        STM32_WR(f->KEYR, STM32_FLASH_KEY1);
        STM32_WR(f->KEYR, STM32_FLASH_KEY2);
    }
    if ((STM32_RD(f->CR) & STM32_FLASH_CR_LOCK) != 0u ||
        wait_idle(drv, drv->cfg.program_polls) != HAL_OK) {
        return HAL_ERR_IO;
    }
    STM32_WR(f->SR, STM32_FLASH_SR_ERRORS | STM32_FLASH_SR_EOP); /* rc_w1: stale flags */
    return HAL_OK;
}

/* Ends an operation (rc: its result, each step having checked the error
 * flags): records and clears the flags, locks. */
static int finish(stm32_flash_drv_t *drv, int rc)
{
    stm32_flash_t *f = drv->cfg.regs;
    uint32_t err = STM32_RD(f->SR) & STM32_FLASH_SR_ERRORS;
    if (err != 0u) {
        STM32_WR(f->SR, err);
    }
    if (rc != HAL_OK) {
        drv->errors++;
        drv->last_sr = err;
    }
    STM32_WR(f->CR, STM32_FLASH_CR_LOCK);
    return rc;
}

static int erase_sector(stm32_flash_drv_t *drv, uint32_t snb)
{
    stm32_flash_t *f = drv->cfg.regs;
    STM32_WR(f->CR, STM32_FLASH_CR_PSIZE_X32 | STM32_FLASH_CR_SER |
                        (snb << STM32_FLASH_CR_SNB_POS));
    STM32_SET(f->CR, STM32_FLASH_CR_STRT);
    int rc = wait_idle(drv, drv->cfg.erase_polls);
    if (rc == HAL_OK && (STM32_RD(f->SR) & STM32_FLASH_SR_ERRORS) != 0u) {
        rc = HAL_ERR_IO;
    }
    STM32_CLR(f->CR, STM32_FLASH_CR_SER | STM32_FLASH_CR_SNB_MASK);
    return rc;
}

/* The data cache may hold words of the erased sector (RM0090 3.5.2):
 * reset it (only allowed while it is disabled). */
static void flush_data_cache(stm32_flash_t *f)
{
    uint32_t acr = STM32_RD(f->ACR);
    if ((acr & STM32_FLASH_ACR_DCEN) != 0u) {
        STM32_WR(f->ACR, acr & ~STM32_FLASH_ACR_DCEN);
        STM32_WR(f->ACR, (acr & ~STM32_FLASH_ACR_DCEN) | STM32_FLASH_ACR_DCRST);
        STM32_WR(f->ACR, acr & ~STM32_FLASH_ACR_DCRST);
    }
}

int stm32_flash_erase(void *ctx, size_t offset, size_t len)
{
    stm32_flash_drv_t *drv = ctx;
    size_t sector = drv->cfg.sector_bytes;
    if (!in_range(drv, offset, len) || len == 0u || offset % sector != 0u || len % sector != 0u) {
        return HAL_ERR_RANGE;
    }
    int rc = unlock(drv);
    for (size_t off = offset; rc == HAL_OK && off < offset + len; off += sector) {
        rc = erase_sector(drv, drv->cfg.first_sector + (uint32_t)(off / sector));
    }
    rc = finish(drv, rc);
    flush_data_cache(drv->cfg.regs);
    return rc;
}

static int program(stm32_flash_drv_t *drv, volatile uint8_t *dst, const uint8_t *src, size_t n)
{
    stm32_flash_t *f = drv->cfg.regs;
    if (n == 4u) {
        STM32_WR(f->CR, STM32_FLASH_CR_PSIZE_X32 | STM32_FLASH_CR_PG);
        uint32_t w = (uint32_t)src[0] | ((uint32_t)src[1] << 8) | ((uint32_t)src[2] << 16) |
                     ((uint32_t)src[3] << 24);
        STM32_MEM_WR32(dst, w);
    } else {
        STM32_WR(f->CR, STM32_FLASH_CR_PSIZE_X8 | STM32_FLASH_CR_PG);
        STM32_MEM_WR8(dst, *src);
    }
    int rc = wait_idle(drv, drv->cfg.program_polls);
    if (rc == HAL_OK && (STM32_RD(f->SR) & STM32_FLASH_SR_ERRORS) != 0u) {
        rc = HAL_ERR_IO;
    }
    for (size_t i = 0; rc == HAL_OK && i < n; i++) {
        if (dst[i] != src[i]) { /* bits that could not go 0 -> 1 */
            rc = HAL_ERR_IO;
        }
    }
    STM32_CLR(f->CR, STM32_FLASH_CR_PG);
    return rc;
}

int stm32_flash_write(void *ctx, size_t offset, const void *buf, size_t len)
{
    stm32_flash_drv_t *drv = ctx;
    if (!in_range(drv, offset, len)) {
        return HAL_ERR_RANGE;
    }
    const uint8_t *src = buf;
    int rc = unlock(drv);
    size_t i = 0;
    while (rc == HAL_OK && i < len) {
        size_t at = offset + i;
        size_t n = ((at & 3u) == 0u && len - i >= 4u) ? 4u : 1u;
        rc = program(drv, drv->cfg.mem + at, src + i, n);
        i += n;
    }
    return finish(drv, rc);
}
