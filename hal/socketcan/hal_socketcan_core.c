/* OS-independent logic of the SocketCAN backend; see hal_socketcan_core.h. */
#include "hal_socketcan_core.h"

#include <string.h>

#include <linux/can/error.h>

void hsc_core_init(hsc_core_t *c, bool fd)
{
    memset(c, 0, sizeof(*c));
    c->fd = fd;
}

uint8_t hsc_fd_len_round_up(uint8_t len)
{
    static const uint8_t fd_lens[] = {12u, 16u, 20u, 24u, 32u, 48u, 64u};
    if (len <= 8u) {
        return len;
    }
    for (size_t i = 0; i < sizeof(fd_lens); ++i) {
        if (len <= fd_lens[i]) {
            return fd_lens[i];
        }
    }
    return 0xFFu; /* > 64: no FD length fits */
}

static bool id_valid(const hal_can_frame_t *f)
{
    uint32_t max = (f->flags & HAL_CAN_FLAG_EXT) ? CAN_EFF_MASK : CAN_SFF_MASK;
    return f->id <= max;
}

bool hsc_frame_valid(const hal_can_frame_t *f, bool fd_allowed)
{
    if (f == NULL || !id_valid(f) || (f->flags & HAL_CAN_FLAG_ERR)) {
        return false;
    }
    if (f->flags & HAL_CAN_FLAG_FD) {
        /* FD has no remote frames; the length must be an FD DLC length. */
        return fd_allowed && !(f->flags & HAL_CAN_FLAG_RTR) &&
               hsc_fd_len_round_up(f->len) == f->len;
    }
    return f->len <= CAN_MAX_DLEN;
}

int hsc_to_linux(const hal_can_frame_t *in, struct canfd_frame *out,
                 size_t *nbytes)
{
    if (!hsc_frame_valid(in, true)) {
        return HAL_ERR_RANGE;
    }
    memset(out, 0, sizeof(*out));
    out->can_id = in->id;
    if (in->flags & HAL_CAN_FLAG_EXT) {
        out->can_id |= CAN_EFF_FLAG;
    }
    if (in->flags & HAL_CAN_FLAG_RTR) {
        out->can_id |= CAN_RTR_FLAG;
    }
    out->len = in->len;
    memcpy(out->data, in->data, in->len);
    /* struct can_frame is a prefix of struct canfd_frame (same layout for
     * id, len and the first 8 data bytes), so one buffer serves both. */
    *nbytes = (in->flags & HAL_CAN_FLAG_FD) ? CANFD_MTU : CAN_MTU;
    return HAL_OK;
}

int hsc_from_linux(const struct canfd_frame *in, size_t nbytes,
                   hal_can_frame_t *out)
{
    size_t max_len;
    if (nbytes == CAN_MTU) {
        max_len = CAN_MAX_DLEN;
    } else if (nbytes == CANFD_MTU) {
        max_len = CANFD_MAX_DLEN;
    } else {
        return HAL_ERR_RANGE;
    }
    if (in->len > max_len) {
        return HAL_ERR_RANGE;
    }
    memset(out, 0, sizeof(*out));
    out->len = in->len;
    if (nbytes == CANFD_MTU) {
        out->flags |= HAL_CAN_FLAG_FD;
    }
    if (in->can_id & CAN_ERR_FLAG) {
        out->flags |= HAL_CAN_FLAG_ERR;
        out->id = in->can_id & CAN_ERR_MASK;
    } else if (in->can_id & CAN_EFF_FLAG) {
        out->flags |= HAL_CAN_FLAG_EXT;
        out->id = in->can_id & CAN_EFF_MASK;
    } else {
        out->id = in->can_id & CAN_SFF_MASK;
    }
    if (in->can_id & CAN_RTR_FLAG) {
        out->flags |= HAL_CAN_FLAG_RTR;
    }
    memcpy(out->data, in->data, in->len);
    return HAL_OK;
}

size_t hsc_build_filters(const uint32_t *ids, size_t n, struct can_filter *out)
{
    if (ids == NULL || n == 0u || n > HAL_SOCKETCAN_MAX_RX_IDS) {
        return 0u;
    }
    for (size_t i = 0; i < n; ++i) {
        uint32_t id = ids[i] & ~HAL_SOCKETCAN_ID_EXT;
        if (ids[i] & HAL_SOCKETCAN_ID_EXT) {
            if (id > CAN_EFF_MASK) {
                return 0u;
            }
            out[i].can_id = id | CAN_EFF_FLAG;
            out[i].can_mask = CAN_EFF_MASK | CAN_EFF_FLAG;
        } else {
            if (id > CAN_SFF_MASK) {
                return 0u;
            }
            /* EFF flag in the mask: a 29-bit frame with the same number
             * is a different message and must not pass. */
            out[i].can_id = id;
            out[i].can_mask = CAN_SFF_MASK | CAN_EFF_FLAG;
        }
    }
    return n;
}

static void txq_push(hsc_core_t *c, const hal_can_frame_t *f)
{
    size_t tail = (c->txq_head + c->txq_count) % HAL_SOCKETCAN_TXQ_LEN;
    c->txq[tail] = *f;
    c->txq_count++;
}

static void txq_pop(hsc_core_t *c)
{
    c->txq_head = (c->txq_head + 1u) % HAL_SOCKETCAN_TXQ_LEN;
    c->txq_count--;
}

int hsc_core_drain(hsc_core_t *c, hsc_write_fn wr, void *io)
{
    /* A bus-off controller transmits nothing: keep the frames until it is
     * back rather than pushing them into a stopped kernel queue. */
    while (c->txq_count > 0u && !c->bus_off) {
        int r = wr(io, &c->txq[c->txq_head]);
        if (r == HSC_IO_AGAIN) {
            return HAL_OK;
        }
        txq_pop(c);
        if (r != 0) {
            c->counters.can_tx_dropped++;
            return HAL_ERR_IO;
        }
        c->counters.can_tx_ok++;
    }
    return HAL_OK;
}

int hsc_core_send(hsc_core_t *c, const hal_can_frame_t *f, hsc_write_fn wr,
                  void *io)
{
    if (!hsc_frame_valid(f, c->fd)) {
        return HAL_ERR_RANGE;
    }
    if (c->bus_off) {
        return HAL_ERR_FAULT;
    }
    int r = hsc_core_drain(c, wr, io);
    if (r != HAL_OK) {
        return r;
    }
    /* Frames already waiting go first, to keep the order on the bus. */
    if (c->txq_count == 0u) {
        r = wr(io, f);
        if (r == 0) {
            c->counters.can_tx_ok++;
            return HAL_OK;
        }
        if (r != HSC_IO_AGAIN) {
            c->counters.can_tx_dropped++;
            return HAL_ERR_IO;
        }
    }
    if (c->txq_count >= HAL_SOCKETCAN_TXQ_LEN) {
        c->counters.can_tx_dropped++;
        return HAL_ERR_BUSY;
    }
    txq_push(c, f);
    return HAL_OK;
}

void hsc_core_error_frame(hsc_core_t *c, const hal_can_frame_t *f)
{
    const uint32_t err_class = f->id;
    c->counters.can_error_frames++;
    /* linux/can/error.h: the controller's lost frames in data[1], its
     * error counters in data[6] (TEC) and data[7] (REC). */
    if ((err_class & CAN_ERR_CRTL) && f->len > 1u &&
        (f->data[1] & CAN_ERR_CRTL_RX_OVERFLOW)) {
        c->counters.can_rx_overruns++;
    }
    if ((err_class & CAN_ERR_CNT) && f->len > 7u) {
        c->counters.can_tx_error_count = f->data[6];
        c->counters.can_rx_error_count = f->data[7];
    }
    /* The netdevice gave up on a frame it had accepted. */
    if (err_class & CAN_ERR_TX_TIMEOUT) {
        c->counters.can_tx_aborted++;
    }
    if (err_class & CAN_ERR_BUSOFF) {
        if (!c->bus_off) {
            c->counters.can_bus_off++;
        }
        c->bus_off = true;
    }
    /* The driver reports a (manual or restart-ms) controller restart. */
    if (err_class & CAN_ERR_RESTARTED) {
        c->bus_off = false;
    }
}

int hsc_core_recv(hsc_core_t *c, hal_can_frame_t *f, hsc_read_fn rd,
                  hsc_write_fn wr, void *io)
{
    int drain = hsc_core_drain(c, wr, io);
    for (unsigned i = 0; i < HSC_RX_BURST; ++i) {
        int r = rd(io, f);
        if (r == HSC_IO_AGAIN) {
            break;
        }
        if (r != 0) {
            return HAL_ERR_IO;
        }
        if (f->flags & HAL_CAN_FLAG_ERR) {
            hsc_core_error_frame(c, f);
            continue;
        }
        /* A frame from another node: the bus carries traffic again. */
        c->bus_off = false;
        c->counters.can_rx++;
        return HAL_OK;
    }
    return drain != HAL_OK ? drain : HAL_ERR_NO_DATA;
}
