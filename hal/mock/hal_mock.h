/*
 * hal_mock: a deterministic, in-memory HAL backend for tests and for the
 * host runner's CAN log.
 *
 * - Sensors: tests queue samples (ADC counts, encoder counts, motor current,
 *   return codes); each adc_read takes the next one, encoder_read and
 *   current_read return the same sample's parts (current_read exists only
 *   when current_channel is set before binding).  An empty queue returns HAL_ERR_END (or HAL_ERR_NO_DATA).
 * - CAN: every transmitted frame is stored (up to HAL_MOCK_TX_CAP) with the
 *   mock clock's time stamp and passed to an optional hook (the runner writes
 *   a candump log from it).  Tests queue received frames, can make the
 *   transmit queue full (HAL_ERR_BUSY) or the bus go off (HAL_ERR_FAULT).
 * - NVM: HAL_MOCK_NVM_BYTES of RAM with flash semantics (erase to 0xFF);
 *   failures can be injected.
 * - Clock: microseconds, advanced by hand or by auto_advance_us per adc_read.
 *
 * No heap, no stdio: builds for the MCU too.  hal_candump_format formats one
 * `candump -l` line without stdio.
 */
#ifndef HAL_MOCK_H
#define HAL_MOCK_H

#include <stdbool.h>
#include <stddef.h>
#include <stdint.h>

#include "hal.h"

#ifdef __cplusplus
extern "C" {
#endif

#define HAL_MOCK_QUEUE 256u
#define HAL_MOCK_TX_CAP 512u
#define HAL_MOCK_RX_CAP 32u
#define HAL_MOCK_NVM_BYTES 4096u  /* two halves of the record store (hd_record_store.h) */

typedef struct {
    int adc_rc;                /* returned by adc_read (HAL_OK or an injected error) */
    hal_adc_sample_t adc;
    int enc_rc;                /* returned by encoder_read */
    hal_encoder_sample_t enc;
    int cur_rc;                /* returned by current_read */
    hal_current_sample_t cur;
} hal_mock_sample_t;

typedef void (*hal_mock_tx_hook_t)(void *hook_ctx, const hal_can_frame_t *frame, uint64_t t_us);

typedef struct {
    /* sensors */
    hal_mock_sample_t samples[HAL_MOCK_QUEUE];
    uint32_t sample_head;
    uint32_t sample_count;
    hal_mock_sample_t current;
    bool empty_is_end;         /* default true: HAL_ERR_END when the queue is empty */
    uint32_t adc_reads;
    bool current_channel;      /* read at bind: false leaves sensors.current_read NULL */

    /* CAN transmit */
    hal_can_frame_t tx[HAL_MOCK_TX_CAP];
    uint64_t tx_t_us[HAL_MOCK_TX_CAP];
    uint32_t tx_stored;
    uint32_t tx_not_stored;    /* sent but beyond HAL_MOCK_TX_CAP */
    bool tx_store;             /* default true */
    int32_t tx_budget;         /* < 0: unlimited; else frames accepted before HAL_ERR_BUSY */
    bool bus_off;              /* send returns HAL_ERR_FAULT */
    hal_mock_tx_hook_t tx_hook;
    void *tx_hook_ctx;

    /* CAN receive */
    hal_can_frame_t rx[HAL_MOCK_RX_CAP];
    uint32_t rx_head;
    uint32_t rx_count;

    hal_counters_t counters;

    /* NVM */
    uint8_t nvm[HAL_MOCK_NVM_BYTES];
    bool nvm_fail;             /* every NVM call returns HAL_ERR_IO */

    /* system */
    uint32_t board_id;         /* hal_system_t.board_id (0 by default), read at bind */
    hal_boot_info_t boot;      /* what boot_info reports */
    bool reboot_supported;     /* read at bind: false leaves system.reboot NULL */
    uint32_t reboots;          /* system.reboot calls */

    /* clock */
    uint64_t now_us;
    uint32_t auto_advance_us;  /* added on every adc_read (default 1000) */
} hal_mock_t;

/* Empty queues, erased NVM, clock at 0, auto advance 1 ms. */
void hal_mock_init(hal_mock_t *m);

/* Points all four parts of hal at the mock. */
void hal_mock_bind(hal_mock_t *m, hal_t *hal);

/* Binds only the CAN part (e.g. to log what a runner sends). */
void hal_mock_bind_can(hal_mock_t *m, hal_can_t *can);

/* Queues one sample; returns 0 or HAL_ERR_BUSY when the queue is full. */
int hal_mock_push_sample(hal_mock_t *m, const hal_mock_sample_t *s);
/* Shorthand for a healthy sample (motor encoder only). */
int hal_mock_push(hal_mock_t *m, int32_t bridge_counts, uint32_t motor_counts);

/* Queues a frame for the firmware to receive. */
int hal_mock_push_rx(hal_mock_t *m, const hal_can_frame_t *f);

uint32_t hal_mock_tx_count(const hal_mock_t *m);
const hal_can_frame_t *hal_mock_tx(const hal_mock_t *m, uint32_t i);
void hal_mock_tx_clear(hal_mock_t *m);

/* Formats one `candump -l` line, "(sssssssss.uuuuuu) IF ID#DATA\n", NUL
 * terminated: classic "123#0011", extended "12345678#..", RTR "123#R",
 * FD "123##0<data>".  Returns the length, or -1 if cap is too small. */
int hal_candump_format(const hal_can_frame_t *f, uint64_t t_us, const char *ifname, char *buf,
                       size_t cap);

#ifdef __cplusplus
}
#endif

#endif /* HAL_MOCK_H */
