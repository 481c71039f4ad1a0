/*
 * hd_ctrl_image: the joint firmware with its control stage on the
 * Cortex-M4F, run by SysTick at 1 kHz in lockstep with a plant on the host
 * (issue 23):
 *
 *   qemu-system-arm -M mps2-an386 -nographic -kernel hd_ctrl_image.elf
 *     -semihosting-config enable=on,target=native,arg=hd_ctrl_image,arg=SAMPLES,arg=COMMANDS
 *     -icount shift=0,sleep=off
 *
 * SAMPLES and COMMANDS are host FIFOs (tools/target closed-loop makes them
 * and runs tests/target/target_plant on their other ends): before each tick
 * the main loop reads one sample record (sensors and the setpoint), after it
 * writes one command record (firmware/board/common/hd_lockstep.h).  The
 * exchange runs with the tick interrupt masked: a semihosting call is one
 * instruction of virtual time under -icount, and a blocked read stops the
 * virtual clock, so the plant's time and the firmware's stay locked.
 * A sample with mode HD_LS_END ends the run: exit status 0.
 *
 * The drive is a recording actuator (its command goes back to the plant's
 * simulated drive), NVM is RAM (empty: the calibration defaults), CAN
 * transmit is counted and dropped.  The SysTick handler is hd_fw_isr, the
 * function the host calls.
 */
#include <stdbool.h>
#include <stdint.h>
#include <string.h>

#include "board.h"
#include "board_io.h"
#include "hal_mock.h"
#include "hd_fw.h"
#include "hd_lockstep.h"
#include "semihost.h"

static hd_fw_t g_fw;
static hal_t g_hal;
static hal_mock_t g_mock;
static hd_ls_drive_t g_drive;
static int g_in = -1, g_out = -1;
static volatile uint32_t g_ticks_run;
static volatile bool g_stop;

void SysTick_Handler(void)
{
    hd_mark_begin();
    hd_fw_isr(&g_fw);
    hd_mark_end();
    if (g_fw.tick.ended) { /* no sample queued: the exchange fell behind */
        board_systick_stop();
        g_stop = true;
        return;
    }
    g_ticks_run = g_ticks_run + 1u;
}

/* Reads exactly n bytes (a FIFO returns what it has); false at the end. */
static bool read_all(int fd, uint8_t *buf, size_t n)
{
    size_t got = 0u;
    while (got < n) {
        const long r = sh_read(fd, buf + got, n - got);
        if (r <= 0) {
            return false;
        }
        got += (size_t)r;
    }
    return true;
}

/* The sample of tick k into the firmware's queues; false at the end. */
static bool next_sample(uint32_t tick)
{
    uint8_t rec[HD_LS_SAMPLE_BYTES];
    hd_ls_sample_t s;
    if (!read_all(g_in, rec, sizeof rec)) {
        return false;
    }
    hd_ls_unpack_sample(rec, &s);
    return s.mode != HD_LS_END && hd_ls_feed(&g_mock, &g_fw, &s, tick) == 0;
}

int main(void)
{
    char *argv[3];
    if (board_args(argv, 3) != 3) {
        sh_puts("usage: hd_ctrl_image SAMPLES COMMANDS  (semihosting arg=...)\n");
        return BOARD_EXIT_USAGE;
    }
    /* the plant opens SAMPLES for writing first, then COMMANDS for reading */
    g_in = sh_open(argv[1], SH_MODE_RB);
    g_out = g_in >= 0 ? sh_open(argv[2], SH_MODE_WB) : -1;
    if (g_in < 0 || g_out < 0) {
        sh_puts("hd_ctrl_image: cannot open the exchange files\n");
        return BOARD_EXIT_IO;
    }
    hal_mock_init(&g_mock);
    hal_mock_bind(&g_mock, &g_hal);
    g_mock.auto_advance_us = 0u;
    g_mock.tx_store = false;
    hd_ls_bind_drive(&g_drive, &g_hal);
    g_hal.name = BOARD_NAME;

    hd_fw_config_t cfg;
    hd_fw_config_default(&cfg);
    int rc = hd_fw_init(&g_fw, &g_hal, &cfg);
    if (rc != HD_FW_OK) {
        sh_puts("hd_ctrl_image: firmware init failed: ");
        sh_puts(hd_fw_err_str(rc));
        sh_puts("\n");
        return BOARD_EXIT_INIT;
    }
    uint32_t written = 0u;
    bool more = next_sample(0u);
    if (more) {
        board_systick_start();
    }
    while (more && !g_stop) {
        board_irq_disable();
        if (g_ticks_run > written) {
            uint8_t rec[HD_LS_COMMAND_BYTES];
            hd_ls_pack_command(&g_fw, &g_drive, written, rec);
            if (sh_write(g_out, rec, sizeof rec) != 0) {
                board_irq_enable();
                sh_puts("hd_ctrl_image: command write failed\n");
                return BOARD_EXIT_IO;
            }
            written++;
            more = next_sample(written);
            if (!more) {
                board_systick_stop();
                board_irq_enable();
                break;
            }
        }
        board_wait_for_interrupt(); /* wakes on the pending SysTick even when masked */
        board_irq_enable();         /* the tick runs here */
        (void)hd_fw_background(&g_fw);
    }
    (void)sh_close(g_out);
    (void)sh_close(g_in);
    board_print_u32("hd_ctrl_image: ticks ", written);
    if (g_stop) {
        sh_puts("hd_ctrl_image: a tick found no sample (the exchange fell behind)\n");
        return BOARD_EXIT_OVERFLOW;
    }
    return BOARD_EXIT_OK;
}
