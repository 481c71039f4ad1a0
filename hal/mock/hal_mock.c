/* hal_mock: see hal_mock.h. */
#include "hal_mock.h"

#include <string.h>

void hal_mock_init(hal_mock_t *m)
{
    memset(m, 0, sizeof *m);
    m->empty_is_end = true;
    m->tx_store = true;
    m->tx_budget = -1;
    m->auto_advance_us = 1000u;
    memset(m->nvm, 0xFF, sizeof m->nvm);
}

static int adc_read(void *ctx, hal_adc_sample_t *out)
{
    hal_mock_t *m = ctx;
    if (m->sample_count == 0u) {
        return m->empty_is_end ? HAL_ERR_END : HAL_ERR_NO_DATA;
    }
    m->current = m->samples[m->sample_head];
    m->sample_head = (m->sample_head + 1u) % HAL_MOCK_QUEUE;
    m->sample_count--;
    m->adc_reads++;
    m->now_us += m->auto_advance_us;
    *out = m->current.adc;
    return m->current.adc_rc;
}

static int encoder_read(void *ctx, hal_encoder_sample_t *out)
{
    hal_mock_t *m = ctx;
    *out = m->current.enc;
    return m->current.enc_rc;
}

static int current_read(void *ctx, hal_current_sample_t *out)
{
    hal_mock_t *m = ctx;
    *out = m->current.cur;
    return m->current.cur_rc;
}

static int can_send(void *ctx, const hal_can_frame_t *f)
{
    hal_mock_t *m = ctx;
    if (f->len > HAL_CAN_MAX_DATA || (f->len > 8u && (f->flags & HAL_CAN_FLAG_FD) == 0u)) {
        return HAL_ERR_RANGE;
    }
    if (m->bus_off) {
        m->counters.can_bus_off++;
        m->counters.can_tx_dropped++;
        return HAL_ERR_FAULT;
    }
    if (m->tx_budget == 0) {
        m->counters.can_tx_dropped++;
        return HAL_ERR_BUSY;
    }
    if (m->tx_budget > 0) {
        m->tx_budget--;
    }
    m->counters.can_tx_ok++;
    if (m->tx_store && m->tx_stored < HAL_MOCK_TX_CAP) {
        m->tx[m->tx_stored] = *f;
        m->tx_t_us[m->tx_stored] = m->now_us;
        m->tx_stored++;
    } else {
        m->tx_not_stored++;
    }
    if (m->tx_hook != NULL) {
        m->tx_hook(m->tx_hook_ctx, f, m->now_us);
    }
    return HAL_OK;
}

static int can_recv(void *ctx, hal_can_frame_t *f)
{
    hal_mock_t *m = ctx;
    if (m->rx_count == 0u) {
        return HAL_ERR_NO_DATA;
    }
    /* The header and the classic frame's 8 bytes (more only for a longer
     * FD frame), not the whole 64-byte buffer: the bench image counts this
     * copy in the tick, and a real driver moves only what the frame has. */
    const hal_can_frame_t *r = &m->rx[m->rx_head];
    f->id = r->id;
    f->len = r->len;
    f->flags = r->flags;
    memcpy(f->data, r->data, 8u);
    if (r->len > 8u) {
        const size_t n = r->len < HAL_CAN_MAX_DATA ? r->len : HAL_CAN_MAX_DATA;
        memcpy(&f->data[8], &r->data[8], n - 8u);
    }
    m->rx_head = (m->rx_head + 1u) % HAL_MOCK_RX_CAP;
    m->rx_count--;
    m->counters.can_rx++;
    return HAL_OK;
}

static void can_counters(void *ctx, hal_counters_t *out)
{
    const hal_mock_t *m = ctx;
    *out = m->counters;
}

static int nvm_check(const hal_mock_t *m, size_t offset, size_t len)
{
    if (m->nvm_fail) {
        return HAL_ERR_IO;
    }
    if (offset > HAL_MOCK_NVM_BYTES || len > HAL_MOCK_NVM_BYTES - offset) {
        return HAL_ERR_RANGE;
    }
    return HAL_OK;
}

static int nvm_read(void *ctx, size_t offset, void *buf, size_t len)
{
    hal_mock_t *m = ctx;
    int rc = nvm_check(m, offset, len);
    if (rc == HAL_OK) {
        memcpy(buf, &m->nvm[offset], len);
    }
    return rc;
}

static int nvm_write(void *ctx, size_t offset, const void *buf, size_t len)
{
    hal_mock_t *m = ctx;
    int rc = nvm_check(m, offset, len);
    if (rc == HAL_OK) {
        /* flash semantics: writing can only clear bits */
        const uint8_t *src = buf;
        for (size_t i = 0; i < len; i++) {
            m->nvm[offset + i] &= src[i];
        }
    }
    return rc;
}

static int nvm_erase(void *ctx, size_t offset, size_t len)
{
    hal_mock_t *m = ctx;
    int rc = nvm_check(m, offset, len);
    if (rc == HAL_OK) {
        memset(&m->nvm[offset], 0xFF, len);
    }
    return rc;
}

static uint64_t time_us(void *ctx)
{
    const hal_mock_t *m = ctx;
    return m->now_us;
}

void hal_mock_bind_can(hal_mock_t *m, hal_can_t *can)
{
    can->ctx = m;
    can->send = can_send;
    can->recv = can_recv;
    can->counters = can_counters;
}

static void boot_info(void *ctx, hal_boot_info_t *out)
{
    const hal_mock_t *m = (const hal_mock_t *)ctx;
    *out = m->boot;
}

static void reboot(void *ctx)
{
    hal_mock_t *m = (hal_mock_t *)ctx;
    m->reboots++;
}

void hal_mock_bind(hal_mock_t *m, hal_t *hal)
{
    memset(hal, 0, sizeof *hal);
    hal->name = "mock";
    hal->sensors.ctx = m;
    hal->sensors.adc_read = adc_read;
    hal->sensors.encoder_read = encoder_read;
    hal->sensors.current_read = m->current_channel ? current_read : NULL;
    hal_mock_bind_can(m, &hal->can);
    hal->nvm.ctx = m;
    hal->nvm.size = HAL_MOCK_NVM_BYTES;
    hal->nvm.read = nvm_read;
    hal->nvm.write = nvm_write;
    hal->nvm.erase = nvm_erase;
    hal->clock.ctx = m;
    hal->clock.time_us = time_us;
    hal->system.ctx = m;
    hal->system.board_id = m->board_id;
    hal->system.boot_info = boot_info;
    hal->system.reboot = m->reboot_supported ? reboot : NULL;
}

int hal_mock_push_sample(hal_mock_t *m, const hal_mock_sample_t *s)
{
    if (m->sample_count >= HAL_MOCK_QUEUE) {
        return HAL_ERR_BUSY;
    }
    m->samples[(m->sample_head + m->sample_count) % HAL_MOCK_QUEUE] = *s;
    m->sample_count++;
    return HAL_OK;
}

int hal_mock_push(hal_mock_t *m, int32_t bridge_counts, uint32_t motor_counts)
{
    hal_mock_sample_t s;
    memset(&s, 0, sizeof s);
    s.adc.bridge_counts = bridge_counts;
    s.enc.motor_counts = motor_counts;
    return hal_mock_push_sample(m, &s);
}

int hal_mock_push_rx(hal_mock_t *m, const hal_can_frame_t *f)
{
    if (m->rx_count >= HAL_MOCK_RX_CAP) {
        return HAL_ERR_BUSY;
    }
    m->rx[(m->rx_head + m->rx_count) % HAL_MOCK_RX_CAP] = *f;
    m->rx_count++;
    return HAL_OK;
}

uint32_t hal_mock_tx_count(const hal_mock_t *m)
{
    return m->tx_stored;
}

const hal_can_frame_t *hal_mock_tx(const hal_mock_t *m, uint32_t i)
{
    return i < m->tx_stored ? &m->tx[i] : NULL;
}

void hal_mock_tx_clear(hal_mock_t *m)
{
    m->tx_stored = 0u;
    m->tx_not_stored = 0u;
}

/* ----------------------------------------------------------- candump line */

static const char HEX[] = "0123456789ABCDEF";

typedef struct {
    char *buf;
    size_t cap;
    size_t n;
    bool overflow;
} out_t;

static void put_c(out_t *o, char c)
{
    if (o->n + 1u < o->cap) {
        o->buf[o->n++] = c;
    } else {
        o->overflow = true;
    }
}

static void put_s(out_t *o, const char *s)
{
    while (*s != '\0') {
        put_c(o, *s++);
    }
}

static void put_hex(out_t *o, uint32_t v, unsigned digits)
{
    for (unsigned i = digits; i > 0u; i--) {
        put_c(o, HEX[(v >> (4u * (i - 1u))) & 0xFu]);
    }
}

static void put_dec(out_t *o, uint64_t v, unsigned min_digits)
{
    char tmp[20];
    unsigned n = 0;
    do {
        tmp[n++] = (char)('0' + (int)(v % 10u));
        v /= 10u;
    } while (v != 0u && n < sizeof tmp);
    while (n < min_digits && n < sizeof tmp) {
        tmp[n++] = '0';
    }
    while (n > 0u) {
        put_c(o, tmp[--n]);
    }
}

int hal_candump_format(const hal_can_frame_t *f, uint64_t t_us, const char *ifname, char *buf,
                       size_t cap)
{
    if (f == NULL || buf == NULL || cap == 0u || f->len > HAL_CAN_MAX_DATA) {
        return -1;
    }
    out_t o = {buf, cap, 0u, false};
    put_c(&o, '(');
    put_dec(&o, t_us / 1000000u, 10u);
    put_c(&o, '.');
    put_dec(&o, t_us % 1000000u, 6u);
    put_s(&o, ") ");
    put_s(&o, ifname != NULL ? ifname : "can0");
    put_c(&o, ' ');
    if ((f->flags & HAL_CAN_FLAG_EXT) != 0u) {
        put_hex(&o, f->id & 0x1FFFFFFFu, 8u);
    } else {
        put_hex(&o, f->id & 0x7FFu, 3u);
    }
    put_c(&o, '#');
    if ((f->flags & HAL_CAN_FLAG_FD) != 0u) {
        put_c(&o, '#');
        put_c(&o, '0'); /* FD flags nibble: no BRS, no ESI */
    } else if ((f->flags & HAL_CAN_FLAG_RTR) != 0u) {
        put_c(&o, 'R');
    }
    if ((f->flags & HAL_CAN_FLAG_RTR) == 0u) {
        for (unsigned i = 0; i < f->len; i++) {
            put_hex(&o, f->data[i], 2u);
        }
    }
    put_c(&o, '\n');
    buf[o.n] = '\0';
    return o.overflow ? -1 : (int)o.n;
}
