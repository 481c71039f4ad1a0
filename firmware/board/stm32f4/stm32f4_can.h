/*
 * stm32f4_can: the bxCAN controller (CAN1) as the HAL's CAN part, classic
 * frames, written from RM0090 section 32.
 *
 * - Bit timing is computed from the APB1 clock (stm32_can_timing): the
 *   largest number of time quanta per bit (8..25) that divides the clock
 *   exactly and puts the sample point closest to 87.5 % (CiA 301), SJW 1.
 *   At 42 MHz this gives prescaler 3, BS1 11, BS2 2 (1 Mbit/s) and
 *   prescaler 6, BS1 11, BS2 2 (500 kbit/s), sample point 85.7 %.
 * - Receive: FIFO 0 through acceptance filters in 32-bit identifier list
 *   mode (two ids per bank, standard or extended): only the ids given to
 *   stm32_can_set_filter (hal_can_t.set_rx_filter: the firmware's command
 *   and feed-forward ids) reach the firmware; no ids = accept everything.
 * - Transmit: the three mailboxes, filled in request order (MCR.TXFP), and
 *   behind them a software queue of STM32_CAN_TXQ frames, drained from the
 *   transmit-mailbox-empty interrupt (stm32_can_tx_service).  A full queue
 *   returns HAL_ERR_BUSY (counted as dropped).
 * - Bus-off: automatic recovery (MCR.ABOM: the controller rejoins after
 *   128 x 11 recessive bits).  While off, send returns HAL_ERR_FAULT; each
 *   entry into bus-off is counted (can_bus_off), and each new bus error
 *   code (ESR.LEC, re-armed to 7 after reading) counts as an error frame.
 *
 * send is called from the tick interrupt and from the main loop, the
 * service from the CAN interrupt: the mailbox/queue hand-over runs with
 * interrupts masked for a bounded few register accesses.
 */
#ifndef STM32F4_CAN_H
#define STM32F4_CAN_H

#include <stdbool.h>
#include <stddef.h>
#include <stdint.h>

#include "hal.h"
#include "stm32f4_regs.h"

#ifdef __cplusplus
extern "C" {
#endif

#define STM32_CAN_TXQ 32u           /* software transmit queue (frames) */
#define STM32_CAN_FILTER_IDS 8u     /* ids stm32_can_set_filter accepts (4 banks) */
#define STM32_CAN_SAMPLE_PERMILLE 875u
#define STM32_CAN_TQ_MIN 8u
#define STM32_CAN_TQ_MAX 25u        /* 1 + BS1 (1..16) + BS2 (1..8) */

typedef struct {
    uint32_t brp;  /* prescaler 1..1024 */
    uint32_t bs1;  /* 1..16 time quanta */
    uint32_t bs2;  /* 1..8 */
    uint32_t sjw;  /* 1..4 */
} stm32_can_timing_t;

/* The timing for bitrate from pclk1_hz (see above); false if no prescaler
 * gives the bit rate exactly with 8..25 quanta. */
bool stm32_can_timing(uint32_t pclk1_hz, uint32_t bitrate, stm32_can_timing_t *out);

/* The BTR register value of a timing. */
uint32_t stm32_can_btr(const stm32_can_timing_t *t);

typedef struct {
    stm32_can_t *can;
    uint32_t pclk1_hz;
    uint32_t bitrate;        /* 1000000 or 500000 (any exact rate works) */
    uint32_t ready_polls;    /* bound on the INAK/SLAK handshakes */
    bool loopback;           /* BTR.LBKM + SILM: self-test without a bus */
} stm32_can_config_t;

/* A frame as a transmit mailbox takes it: TIR (without TXRQ), TDTR, TDLR,
 * TDHR.  Built once per send; the queue holds these 16 bytes, not a
 * 72-byte hal_can_frame_t. */
typedef struct {
    uint32_t tir;
    uint32_t tdtr;
    uint32_t tdlr;
    uint32_t tdhr;
} stm32_can_tx_words_t;

typedef struct {
    stm32_can_config_t cfg;
    stm32_can_timing_t timing;
    stm32_can_tx_words_t txq[STM32_CAN_TXQ];
    uint32_t txq_head;
    uint32_t txq_count;
    hal_counters_t counters; /* can_tx_aborted: a mailbox completed without TXOK;
                                TEC/REC: ESR at the last look */
    bool bus_off;            /* ESR.BOFF at the last look */
    bool running;            /* left initialization mode */
} stm32_can_drv_t;

/* Wakes the controller from sleep, enters initialization mode (INRQ/INAK),
 * programs bit timing, ABOM and TXFP, deactivates every filter and leaves
 * initialization (INAK clears after 11 recessive bits on the bus).
 * Returns 0, HAL_ERR_RANGE (no exact bit timing) or HAL_ERR_IO (a
 * handshake did not complete: no clock, or RX held dominant). */
int stm32_can_init(stm32_can_drv_t *drv, const stm32_can_config_t *cfg);

/* hal_can_t.set_rx_filter: accepts exactly these ids into FIFO 0 (11-bit,
 * or 29-bit with HAL_CAN_ID_EXT_BIT); n = 0 accepts everything.  Returns 0
 * or HAL_ERR_RANGE (n > STM32_CAN_FILTER_IDS, an id too large for its
 * format).  May be called while running: reception pauses for the few
 * register writes of filter initialization mode. */
int stm32_can_set_filter(void *ctx, const uint32_t *ids, size_t n);

/* hal_can_t functions (ctx = the driver). */
int stm32_can_send(void *ctx, const hal_can_frame_t *frame);
int stm32_can_recv(void *ctx, hal_can_frame_t *frame);
void stm32_can_counters(void *ctx, hal_counters_t *out);

/* Collects finished mailboxes (TXOK counted), refills them from the
 * software queue, and reads the error state (bus-off entries, new bus
 * errors, TEC/REC).  Called from the transmit interrupt and each tick. */
void stm32_can_tx_service(stm32_can_drv_t *drv);

#ifdef __cplusplus
}
#endif

#endif /* STM32F4_CAN_H */
