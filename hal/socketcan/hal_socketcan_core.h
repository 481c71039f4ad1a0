/*
 * Internal, OS-independent part of the SocketCAN backend: frame conversion
 * between hal_can_frame_t and Linux struct can_frame / canfd_frame, the
 * bounded transmit queue, and the error/bus-off state machine.  The socket
 * I/O is passed in as two functions so this logic is unit-tested on hosts
 * without PF_CAN (tests/vm/test_socketcan_core.c) and used unchanged by
 * hal_socketcan.c on a real socket.
 */
#ifndef HAL_SOCKETCAN_CORE_H
#define HAL_SOCKETCAN_CORE_H

#include <stdbool.h>
#include <stddef.h>
#include <stdint.h>

#include <linux/can.h>

#include "hal.h"
#include "hal_socketcan.h"

#ifdef __cplusplus
extern "C" {
#endif

/* At most this many socket reads per recv call (error frames are consumed
 * inside recv), so one call has a bounded cost even under an error storm. */
#define HSC_RX_BURST 16u

/* I/O results besides 0 (= done) and negative hal_err_t. */
#define HSC_IO_AGAIN 1 /* the socket would block (EAGAIN, ENOBUFS) / nothing to read */

/* write: 0 = the kernel took the frame, HSC_IO_AGAIN, or HAL_ERR_IO.
 * read: 0 = *frame filled (error frames carry HAL_CAN_FLAG_ERR, the error
 * class bits in id and the error data in data[0..7]), HSC_IO_AGAIN when
 * nothing waits, HAL_ERR_IO. */
typedef int (*hsc_write_fn)(void *io, const hal_can_frame_t *frame);
typedef int (*hsc_read_fn)(void *io, hal_can_frame_t *frame);

typedef struct {
    hal_can_frame_t txq[HAL_SOCKETCAN_TXQ_LEN];
    size_t txq_head;  /* index of the oldest queued frame */
    size_t txq_count;
    bool fd;          /* CAN FD frames allowed */
    bool bus_off;
    hal_counters_t counters;
} hsc_core_t;

void hsc_core_init(hsc_core_t *c, bool fd);

/* Valid for this link?  Classic: len 0..8; FD: len one of the FD lengths
 * (0-8, 12, 16, 20, 24, 32, 48, 64), no RTR; id fits 11 or 29 bits. */
bool hsc_frame_valid(const hal_can_frame_t *f, bool fd_allowed);

/* Smallest FD length >= len (FD frames are padded with zeros). */
uint8_t hsc_fd_len_round_up(uint8_t len);

/* hal -> Linux.  Writes *out (zeroed first) and the byte count to write
 * (CAN_MTU or CANFD_MTU).  Returns 0 or HAL_ERR_RANGE. */
int hsc_to_linux(const hal_can_frame_t *in, struct canfd_frame *out,
                 size_t *nbytes);
/* Linux -> hal, from nbytes read (CAN_MTU or CANFD_MTU).  Returns 0 or
 * HAL_ERR_RANGE for a short/odd read or an out-of-range length. */
int hsc_from_linux(const struct canfd_frame *in, size_t nbytes,
                   hal_can_frame_t *out);

/* Fills filters for the node's command IDs (HAL_SOCKETCAN_ID_EXT marks a
 * 29-bit id).  Returns the number written, or 0 for an id that does not
 * fit (or n > HAL_SOCKETCAN_MAX_RX_IDS). */
size_t hsc_build_filters(const uint32_t *ids, size_t n, struct can_filter *out);

/* Writes queued frames until the queue is empty or the socket would block.
 * Returns 0, or HAL_ERR_IO (the frame that failed is dropped and counted). */
int hsc_core_drain(hsc_core_t *c, hsc_write_fn wr, void *io);

/* hal_can_t.send semantics: HAL_OK when the kernel or the software queue
 * took the frame, HAL_ERR_BUSY (+ can_tx_dropped) when the queue is full,
 * HAL_ERR_FAULT while bus-off, HAL_ERR_RANGE for a bad frame, HAL_ERR_IO. */
int hsc_core_send(hsc_core_t *c, const hal_can_frame_t *f, hsc_write_fn wr,
                  void *io);

/* hal_can_t.recv semantics: drains the queue, then returns the next data
 * frame (HAL_OK), HAL_ERR_NO_DATA, or HAL_ERR_IO.  Error frames are counted
 * and update the bus-off state; they are not returned. */
int hsc_core_recv(hsc_core_t *c, hal_can_frame_t *f, hsc_read_fn rd,
                  hsc_write_fn wr, void *io);

/* Accounts one error frame (id: the error class bits of linux/can/error.h;
 * data as there): error frames, bus-off and restart, receive overflows
 * (CAN_ERR_CRTL_RX_OVERFLOW), TX timeouts as aborted frames, and the
 * controller's TEC/REC when the class has CAN_ERR_CNT. */
void hsc_core_error_frame(hsc_core_t *c, const hal_can_frame_t *f);

#ifdef __cplusplus
}
#endif

#endif /* HAL_SOCKETCAN_CORE_H */
