/*
 * hal_socketcan: the CAN part of the HAL on Linux SocketCAN (PF_CAN raw
 * sockets: can0, vcan0, ...).  Host-only backend: it allocates its context
 * and uses the OS.
 *
 * Behaviour (see docs/how-to/socketcan.md):
 *  - the socket is non-blocking; send() never waits;
 *  - a bounded software transmit queue (HAL_SOCKETCAN_TXQ_LEN frames) holds
 *    frames the kernel refused with EAGAIN/ENOBUFS; it is drained at every
 *    send/recv call; when it is full send() returns HAL_ERR_BUSY and counts
 *    can_tx_dropped;
 *  - error frames are received (CAN_RAW_ERR_FILTER) and counted inside
 *    recv() (never returned to the caller; at most HSC_RX_BURST socket reads
 *    per call); bus-off (CAN_ERR_BUSOFF) is counted once per event and
 *    send() returns HAL_ERR_FAULT (frame not sent, queue not drained) until
 *    the driver reports a restart (CAN_ERR_RESTARTED) or a data frame from
 *    another node is received;
 *  - only this node's command IDs pass the receive filter (CAN_RAW_FILTER);
 *  - with fd = true the socket accepts and sends CAN FD frames
 *    (CAN_RAW_FD_FRAMES).
 */
#ifndef HAL_SOCKETCAN_H
#define HAL_SOCKETCAN_H

#include <stdbool.h>
#include <stddef.h>
#include <stdint.h>

#include "hal.h"

#ifdef __cplusplus
extern "C" {
#endif

#define HAL_SOCKETCAN_TXQ_LEN 64u     /* software transmit queue, frames */
#define HAL_SOCKETCAN_MAX_RX_IDS 16u  /* receive filter entries */

typedef struct hal_socketcan hal_socketcan_t; /* opaque; allocated by open */

/* Opens a raw CAN socket on `ifname`.  rx_ids: the identifiers this node
 * accepts (standard 11-bit unless HAL_SOCKETCAN_ID_EXT is or-ed in); n_rx_ids
 * == 0 accepts every frame.  Returns NULL and writes a message into err on
 * failure (no PF_CAN in the kernel, no such interface, too many IDs, ...). */
#define HAL_SOCKETCAN_ID_EXT HAL_CAN_ID_EXT_BIT
hal_socketcan_t *hal_socketcan_open(const char *ifname, const uint32_t *rx_ids,
                                    size_t n_rx_ids, bool fd, char *err,
                                    size_t errlen);

/* Fills the hal_can_t part of hal/hal.h (ctx, send, recv, counters). */
void hal_socketcan_bind(hal_socketcan_t *s, hal_can_t *can);

/* Closes the socket and frees the context; NULL is accepted. */
void hal_socketcan_close(hal_socketcan_t *s);

/* Direct access for tools and tests (same as through hal_can_t). */
int hal_socketcan_send(hal_socketcan_t *s, const hal_can_frame_t *frame);
int hal_socketcan_recv(hal_socketcan_t *s, hal_can_frame_t *frame);
void hal_socketcan_counters(const hal_socketcan_t *s, hal_counters_t *out);
/* Frames waiting in the software queue. */
size_t hal_socketcan_tx_pending(const hal_socketcan_t *s);
/* True while the controller is bus-off (last error frame said so and no
 * frame has flowed since). */
bool hal_socketcan_bus_off(const hal_socketcan_t *s);

#ifdef __cplusplus
}
#endif

#endif /* HAL_SOCKETCAN_H */
