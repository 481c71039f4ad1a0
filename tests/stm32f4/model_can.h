/*
 * model_can: a register-level model of the bxCAN controller (RM0090
 * section 32) for the driver tests: reset values, the sleep / init /
 * normal mode handshake (MCR.SLEEP/INRQ -> MSR.SLAK/INAK, acknowledged
 * after `ack_reads` reads of MSR; leaving init needs a recessive bus),
 * registers writable only in initialization mode (BTR) or filter
 * initialization mode (FM1R, FS1R, FFA1R), the three transmit mailboxes
 * (TME flags, TXRQ, RQCP/TXOK cleared by writing 1, transmit order by
 * request (TXFP) or by identifier), receive FIFO 0 (three frames, FMP
 * count, RFOM release, FULL and FOVR), the acceptance filters (16/32-bit,
 * list/mask) and the error state (LEC, TEC/REC, error warning/passive,
 * bus-off and automatic recovery).  The bus is stepped by the test.
 * Anything the manual forbids (a busy mailbox written, BTR outside init)
 * is counted in `violations`.
 */
#ifndef MODEL_CAN_H
#define MODEL_CAN_H

#include <stdbool.h>
#include <stddef.h>
#include <stdint.h>

#include "hal.h"
#include "reg_model.h"

#define CAN_MODEL_WIRE 512u

typedef enum { CAN_MODE_SLEEP, CAN_MODE_INIT, CAN_MODE_NORMAL } can_mode_t;

typedef struct {
    reg_model_t rm;
    stm32_can_t regs;
    can_mode_t mode;
    uint32_t ack_reads;        /* MSR reads until a mode request is acknowledged */
    uint32_t ack_left;
    bool ack_pending;
    bool bus_dominant;         /* RX held dominant: normal mode is never reached */
    bool no_clock;             /* peripheral clock off: MSR never changes */
    /* transmit */
    uint32_t tx_order[3];
    uint32_t tx_seq;
    hal_can_frame_t wire[CAN_MODEL_WIRE];
    size_t wire_count;
    /* receive FIFO 0 */
    hal_can_frame_t fifo[3];
    size_t fifo_count;
    uint32_t rx_overwritten;
    /* errors */
    uint32_t tec, rec;
    bool boff;
    uint32_t recovery_steps;   /* bus steps of 128 x 11 recessive bits to recover */
    uint32_t recovery_left;
    uint32_t inject_errors;    /* next steps that end in a bus error instead of a frame */
    uint32_t inject_lec;       /* the error code they leave in ESR.LEC (1..6) */
    uint32_t violations;
    const char *last_violation;
} can_model_t;

/* Reset values, registered with reg_model. */
void can_model_init(can_model_t *m);

/* One frame time on the bus: recovers from bus-off, or raises an injected
 * error, or transmits the next pending mailbox.  Returns true if a frame
 * was transmitted. */
bool can_model_bus_step(can_model_t *m);

/* A frame from another node; returns true if it passed the filters into
 * FIFO 0. */
bool can_model_deliver(can_model_t *m, const hal_can_frame_t *f);

#endif /* MODEL_CAN_H */
