/*
 * hd_image: the joint firmware on the Cortex-M4F, run by SysTick at 1 kHz.
 *
 *   qemu-system-arm -M mps2-an386 -nographic -kernel hd_image.elf
 *     -semihosting-config enable=on,target=native,arg=hd_image,arg=IN.hdraw,arg=OUT.bin,arg=CAN.log
 *     -icount shift=0,sleep=off
 *
 * Sensors come from the raw stream IN.hdraw on the host (hal/semihost), NVM
 * is RAM (hal_mock: empty, so the calibration defaults are used, as with
 * `hdjoint-host --sensors replay:IN.hdraw`), transmitted CAN frames go to
 * CAN.log in `candump -l` format with the sample time as time stamp, and
 * one 28-byte record per tick goes to OUT.bin (docs/results/target.md):
 *   u32 tick, i32 bridge_counts, f32 torque_raw_nm, f32 torque_filtered_nm,
 *   f32 ripple_nm, u32 faults, u32 kf_status     (little-endian, float bits)
 * Either output may be "-" (not written).  When the stream ends the image
 * exits with status 0 (SYS_EXIT_EXTENDED), or a BOARD_EXIT_* code.
 *
 * The SysTick handler is the firmware's ISR: hd_fw_isr, the same function
 * the host runner calls.  The main loop writes the buffered output to the
 * host between ticks and runs hd_fw_background.
 */
#include <stdbool.h>
#include <stdint.h>
#include <string.h>

#include "board.h"
#include "board_io.h"
#include "hal_mock.h"
#include "hal_semihost.h"
#include "hd_fw.h"
#include "semihost.h"

#define DUMP_RECORD_BYTES 28u

static hd_fw_t g_fw;
static hal_t g_hal;
static hal_mock_t g_mock;       /* NVM (RAM), CAN transmit hook, clock */
static hal_sh_stream_t g_stream;
static hal_sh_writer_t g_dump;
static hal_sh_writer_t g_canlog;
static bool g_dump_on;
static bool g_can_on;
static volatile bool g_done;
static volatile uint32_t g_tick;

static uint32_t float_bits(float f)
{
    uint32_t u;
    memcpy(&u, &f, sizeof u);
    return u;
}

void SysTick_Handler(void)
{
    hd_mark_begin();
    g_mock.now_us = (uint64_t)g_tick * HD_FW_TS_US; /* CAN log time: the sample time */
    hd_fw_isr(&g_fw);
    hd_mark_end();
    if (g_fw.tick.ended) {
        board_systick_stop();
        g_done = true;
        return;
    }
    if (g_dump_on) {
        const hd_fw_sample_t *s = hd_fw_last_sample(&g_fw);
        uint8_t rec[DUMP_RECORD_BYTES];
        board_put_le32(&rec[0], g_tick);
        board_put_le32(&rec[4], (uint32_t)s->bridge_counts);
        board_put_le32(&rec[8], float_bits(s->torque_raw_nm));
        board_put_le32(&rec[12], float_bits(s->torque_filtered_nm));
        board_put_le32(&rec[16], float_bits(s->ripple_nm));
        board_put_le32(&rec[20], s->faults);
        board_put_le32(&rec[24], s->kf_status);
        (void)hal_sh_writer_append(&g_dump, rec, sizeof rec);
    }
    g_tick = g_tick + 1u;
}

/* Host I/O with the tick interrupt masked: a semihosting call is one
 * instruction of virtual time under -icount, so no tick is delayed. */
static void flush_outputs(void)
{
    if (g_dump_on) {
        (void)hal_sh_writer_flush(&g_dump);
    }
    if (g_can_on) {
        (void)hal_sh_writer_flush(&g_canlog);
    }
}

int main(void)
{
    char *argv[4];
    int argc = board_args(argv, 4);
    if (argc != 4) {
        sh_puts("usage: hd_image IN.hdraw OUT.bin|- CAN.log|-  (semihosting arg=...)\n");
        return BOARD_EXIT_USAGE;
    }
    int rc = hal_sh_stream_open(&g_stream, argv[1]);
    if (rc != HAL_OK) {
        sh_puts("hd_image: ");
        sh_puts(argv[1]);
        sh_puts(": ");
        sh_puts(g_stream.reader.why);
        sh_puts("\n");
        return rc == HAL_ERR_IO ? BOARD_EXIT_IO : BOARD_EXIT_STREAM;
    }
    if (g_stream.reader.ts_us != HD_FW_TS_US) {
        sh_puts("hd_image: the stream's sample period is not the firmware's 1000 us\n");
        return BOARD_EXIT_STREAM;
    }
    g_dump_on = strcmp(argv[2], "-") != 0;
    g_can_on = strcmp(argv[3], "-") != 0;
    if ((g_dump_on && hal_sh_writer_open(&g_dump, argv[2]) != HAL_OK) ||
        (g_can_on && hal_sh_writer_open(&g_canlog, argv[3]) != HAL_OK)) {
        sh_puts("hd_image: cannot create an output file\n");
        return BOARD_EXIT_IO;
    }

    hal_mock_init(&g_mock);
    hal_mock_bind(&g_mock, &g_hal);
    g_mock.auto_advance_us = 0u;
    g_mock.tx_store = false;
    if (g_can_on) {
        g_mock.tx_hook = hal_sh_canlog_hook;
        g_mock.tx_hook_ctx = &g_canlog;
    }
    hal_sh_stream_bind(&g_stream, &g_hal); /* sensors and the sample clock */
    g_hal.name = BOARD_NAME;

    hd_fw_config_t cfg;
    hd_fw_config_default(&cfg);
    rc = hd_fw_init(&g_fw, &g_hal, &cfg);
    if (rc != HD_FW_OK) {
        sh_puts("hd_image: firmware init failed: ");
        sh_puts(hd_fw_err_str(rc));
        sh_puts("\n");
        return BOARD_EXIT_INIT;
    }

    board_systick_start();
    for (;;) {
        board_irq_disable();
        flush_outputs();
        if (g_done) {
            board_irq_enable();
            break;
        }
        board_wait_for_interrupt(); /* wakes on the pending SysTick even when masked */
        board_irq_enable();         /* the tick runs here */
        (void)hd_fw_background(&g_fw);
    }
    flush_outputs();

    bool lost = g_dump.dropped_bytes != 0u || g_canlog.dropped_bytes != 0u ||
                g_dump.io_errors != 0u || g_canlog.io_errors != 0u || g_stream.reader.io_errors != 0u;
    if (g_dump_on) {
        (void)hal_sh_writer_close(&g_dump);
    }
    if (g_can_on) {
        (void)hal_sh_writer_close(&g_canlog);
    }
    hal_sh_stream_close(&g_stream);
    board_print_u32("hd_image: ticks ", g_tick);
    board_print_u32("hd_image: valid_samples ", hd_fw_counters(&g_fw)->valid_samples);
    if (lost) {
        sh_puts("hd_image: output lost (buffer overflow or host I/O error)\n");
        return BOARD_EXIT_OVERFLOW;
    }
    return BOARD_EXIT_OK;
}
