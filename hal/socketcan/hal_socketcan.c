/*
 * SocketCAN backend: a non-blocking PF_CAN raw socket around the
 * OS-independent core (hal_socketcan_core.c).  Host-only: allocates its
 * context and uses the OS.
 */
#define _GNU_SOURCE /* SOCK_NONBLOCK, SOCK_CLOEXEC */
#include "hal_socketcan.h"

#include <errno.h>
#include <net/if.h>
#include <stdarg.h>
#include <stdio.h>
#include <stdlib.h>
#include <string.h>
#include <sys/ioctl.h>
#include <sys/socket.h>
#include <unistd.h>

#include <linux/can.h>
#include <linux/can/error.h>
#include <linux/can/raw.h>

#include "hal_socketcan_core.h"

struct hal_socketcan {
    int sock;
    hsc_core_t core;
    char ifname[IF_NAMESIZE];
};

static void set_err(char *err, size_t errlen, const char *fmt, ...)
    __attribute__((format(printf, 3, 4)));
static void set_err(char *err, size_t errlen, const char *fmt, ...)
{
    if (err == NULL || errlen == 0u) {
        return;
    }
    va_list ap;
    va_start(ap, fmt);
    vsnprintf(err, errlen, fmt, ap);
    va_end(ap);
}

static int sock_write(void *io, const hal_can_frame_t *frame)
{
    hal_socketcan_t *s = io;
    struct canfd_frame lf;
    size_t nbytes;
    if (hsc_to_linux(frame, &lf, &nbytes) != HAL_OK) {
        return HAL_ERR_IO; /* cannot happen: send validated the frame */
    }
    ssize_t n = write(s->sock, &lf, nbytes);
    if (n == (ssize_t)nbytes) {
        return 0;
    }
    /* ENOBUFS: the interface queue is full (the usual case on a real
     * controller); EAGAIN: the socket send buffer is full. */
    if (n < 0 && (errno == EAGAIN || errno == EWOULDBLOCK || errno == ENOBUFS ||
                  errno == EINTR)) {
        return HSC_IO_AGAIN;
    }
    return HAL_ERR_IO;
}

static int sock_read(void *io, hal_can_frame_t *frame)
{
    hal_socketcan_t *s = io;
    struct canfd_frame lf;
    ssize_t n = read(s->sock, &lf, sizeof(lf));
    if (n < 0) {
        return (errno == EAGAIN || errno == EWOULDBLOCK || errno == EINTR)
                   ? HSC_IO_AGAIN
                   : HAL_ERR_IO;
    }
    return hsc_from_linux(&lf, (size_t)n, frame) == HAL_OK ? 0 : HAL_ERR_IO;
}

/* Sets the socket options; returns 0 or -1 with err filled. */
static int configure(hal_socketcan_t *s, const uint32_t *rx_ids, size_t n_rx_ids,
                     bool fd, char *err, size_t errlen)
{
    if (fd) {
        int on = 1;
        if (setsockopt(s->sock, SOL_CAN_RAW, CAN_RAW_FD_FRAMES, &on, sizeof(on)) != 0) {
            set_err(err, errlen, "socketcan %s: CAN FD not supported by the kernel: %s",
                    s->ifname, strerror(errno));
            return -1;
        }
    }
    /* Every error class: each is counted, bus-off changes the state. */
    can_err_mask_t err_mask = CAN_ERR_MASK;
    if (setsockopt(s->sock, SOL_CAN_RAW, CAN_RAW_ERR_FILTER, &err_mask,
                   sizeof(err_mask)) != 0) {
        set_err(err, errlen, "socketcan %s: CAN_RAW_ERR_FILTER: %s", s->ifname,
                strerror(errno));
        return -1;
    }
    if (n_rx_ids > 0u) {
        struct can_filter filters[HAL_SOCKETCAN_MAX_RX_IDS];
        if (hsc_build_filters(rx_ids, n_rx_ids, filters) != n_rx_ids) {
            set_err(err, errlen,
                    "socketcan %s: bad receive id list (%zu ids, max %u; 11-bit ids "
                    "<= 0x7FF, 29-bit ids need HAL_SOCKETCAN_ID_EXT)",
                    s->ifname, n_rx_ids, HAL_SOCKETCAN_MAX_RX_IDS);
            return -1;
        }
        if (setsockopt(s->sock, SOL_CAN_RAW, CAN_RAW_FILTER, filters,
                       (socklen_t)(n_rx_ids * sizeof(filters[0]))) != 0) {
            set_err(err, errlen, "socketcan %s: CAN_RAW_FILTER: %s", s->ifname,
                    strerror(errno));
            return -1;
        }
    }
    return 0;
}

/* Resolves and binds the interface; returns 0 or -1 with err filled. */
static int bind_iface(hal_socketcan_t *s, bool fd, char *err, size_t errlen)
{
    struct ifreq ifr;
    memset(&ifr, 0, sizeof(ifr));
    memcpy(ifr.ifr_name, s->ifname, sizeof(s->ifname));
    if (ioctl(s->sock, SIOCGIFINDEX, &ifr) != 0) {
        set_err(err, errlen, "socketcan: no CAN interface '%s' (%s); create it with "
                "'ip link add dev %s type vcan' or bring up a real one",
                s->ifname, strerror(errno), s->ifname);
        return -1;
    }
    int ifindex = ifr.ifr_ifindex;
    if (fd) {
        /* An FD socket on a classic-only interface would fail on each FD
         * write; say so at open instead. */
        if (ioctl(s->sock, SIOCGIFMTU, &ifr) != 0 || ifr.ifr_mtu != (int)CANFD_MTU) {
            set_err(err, errlen, "socketcan %s: interface is not CAN FD capable (mtu %d, "
                    "need %d: 'ip link set %s mtu 72' or 'type can fd on')",
                    s->ifname, ifr.ifr_mtu, (int)CANFD_MTU, s->ifname);
            return -1;
        }
    }
    struct sockaddr_can addr;
    memset(&addr, 0, sizeof(addr));
    addr.can_family = AF_CAN;
    addr.can_ifindex = ifindex;
    if (bind(s->sock, (struct sockaddr *)&addr, sizeof(addr)) != 0) {
        set_err(err, errlen, "socketcan %s: bind: %s", s->ifname, strerror(errno));
        return -1;
    }
    return 0;
}

hal_socketcan_t *hal_socketcan_open(const char *ifname, const uint32_t *rx_ids,
                                    size_t n_rx_ids, bool fd, char *err,
                                    size_t errlen)
{
    set_err(err, errlen, "ok");
    if (ifname == NULL || ifname[0] == '\0' || strlen(ifname) >= IF_NAMESIZE) {
        set_err(err, errlen, "socketcan: bad interface name '%s' (1..%d characters)",
                ifname ? ifname : "(null)", IF_NAMESIZE - 1);
        return NULL;
    }
    if (n_rx_ids > 0u && (rx_ids == NULL || n_rx_ids > HAL_SOCKETCAN_MAX_RX_IDS)) {
        set_err(err, errlen, "socketcan %s: %zu receive ids (max %u)", ifname,
                n_rx_ids, HAL_SOCKETCAN_MAX_RX_IDS);
        return NULL;
    }
    hal_socketcan_t *s = calloc(1, sizeof(*s));
    if (s == NULL) {
        set_err(err, errlen, "socketcan %s: out of memory", ifname);
        return NULL;
    }
    strncpy(s->ifname, ifname, sizeof(s->ifname) - 1u);
    hsc_core_init(&s->core, fd);
    s->sock = socket(PF_CAN, SOCK_RAW | SOCK_NONBLOCK | SOCK_CLOEXEC, CAN_RAW);
    if (s->sock < 0) {
        set_err(err, errlen, "socketcan %s: socket(PF_CAN, SOCK_RAW, CAN_RAW) failed: %s "
                "(kernel without CAN support? try 'modprobe can-raw')",
                ifname, strerror(errno));
        free(s);
        return NULL;
    }
    if (configure(s, rx_ids, n_rx_ids, fd, err, errlen) != 0 ||
        bind_iface(s, fd, err, errlen) != 0) {
        close(s->sock);
        free(s);
        return NULL;
    }
    return s;
}

int hal_socketcan_send(hal_socketcan_t *s, const hal_can_frame_t *frame)
{
    return hsc_core_send(&s->core, frame, sock_write, s);
}

int hal_socketcan_recv(hal_socketcan_t *s, hal_can_frame_t *frame)
{
    return hsc_core_recv(&s->core, frame, sock_read, sock_write, s);
}

void hal_socketcan_counters(const hal_socketcan_t *s, hal_counters_t *out)
{
    *out = s->core.counters;
}

size_t hal_socketcan_tx_pending(const hal_socketcan_t *s)
{
    return s->core.txq_count;
}

bool hal_socketcan_bus_off(const hal_socketcan_t *s)
{
    return s->core.bus_off;
}

static int can_send(void *ctx, const hal_can_frame_t *frame)
{
    return hal_socketcan_send(ctx, frame);
}

static int can_recv(void *ctx, hal_can_frame_t *frame)
{
    return hal_socketcan_recv(ctx, frame);
}

static void can_counters(void *ctx, hal_counters_t *out)
{
    hal_socketcan_counters(ctx, out);
}

/* hal_can_t.set_rx_filter: the firmware narrows the kernel filter to its
 * node's frames (at init and after a node-id change). */
static int can_set_rx_filter(void *ctx, const uint32_t *ids, size_t n)
{
    hal_socketcan_t *s = (hal_socketcan_t *)ctx;
    struct can_filter filters[HAL_SOCKETCAN_MAX_RX_IDS];
    if (n == 0u) {
        return setsockopt(s->sock, SOL_CAN_RAW, CAN_RAW_FILTER, NULL, 0) == 0 ? HAL_OK
                                                                            : HAL_ERR_IO;
    }
    if (hsc_build_filters(ids, n, filters) != n) {
        return HAL_ERR_RANGE;
    }
    return setsockopt(s->sock, SOL_CAN_RAW, CAN_RAW_FILTER, filters,
                      (socklen_t)(n * sizeof(filters[0]))) == 0
               ? HAL_OK
               : HAL_ERR_IO;
}

void hal_socketcan_bind(hal_socketcan_t *s, hal_can_t *can)
{
    can->ctx = s;
    can->send = can_send;
    can->recv = can_recv;
    can->counters = can_counters;
    can->set_rx_filter = can_set_rx_filter;
}

void hal_socketcan_close(hal_socketcan_t *s)
{
    if (s == NULL) {
        return;
    }
    /* Give queued frames one last chance; whatever the kernel refuses now
     * is lost with the socket. */
    (void)hsc_core_drain(&s->core, sock_write, s);
    close(s->sock);
    free(s);
}
