/*
 * target_hostref: the host half of the host-vs-Cortex-M4 comparison.
 *
 *   target_hostref IN.hdraw OUT.bin
 *
 * Runs the firmware ISR (hd_fw_isr, host build) over a raw sample stream
 * exactly as `hdjoint-host --sensors replay:IN.hdraw` does (hal/replay for
 * the sensors and clock, hal_mock for NVM and CAN, default configuration,
 * no calibration record) and writes the same 28-byte per-tick records as the
 * QEMU image (firmware/board/mps2_an386/main_run.c):
 *   u32 tick, i32 bridge_counts, f32 torque_raw_nm, f32 torque_filtered_nm,
 *   f32 ripple_nm, u32 faults, u32 kf_status      (little-endian, float bits)
 * The two files must be equal byte for byte.
 */
#include <stdint.h>
#include <stdio.h>
#include <string.h>

#include "hal_mock.h"
#include "hal_replay.h"
#include "hd_fw.h"

static hal_mock_t g_mock;
static hd_fw_t g_fw;

static void put_le32(uint8_t *p, uint32_t v)
{
    p[0] = (uint8_t)v;
    p[1] = (uint8_t)(v >> 8);
    p[2] = (uint8_t)(v >> 16);
    p[3] = (uint8_t)(v >> 24);
}

static uint32_t float_bits(float f)
{
    uint32_t u;
    memcpy(&u, &f, sizeof u);
    return u;
}

int main(int argc, char **argv)
{
    if (argc != 3) {
        fprintf(stderr, "usage: target_hostref IN.hdraw OUT.bin\n");
        return 2;
    }
    char err[256];
    hal_replay_t *replay = hal_replay_open(argv[1], err, sizeof err);
    if (replay == NULL) {
        fprintf(stderr, "target_hostref: %s\n", err);
        return 1;
    }
    if (hal_replay_ts_us(replay) != HD_FW_TS_US) {
        fprintf(stderr, "target_hostref: sample period is not 1000 us\n");
        hal_replay_close(replay);
        return 1;
    }
    FILE *out = fopen(argv[2], "wb");
    if (out == NULL) {
        fprintf(stderr, "target_hostref: cannot write %s\n", argv[2]);
        hal_replay_close(replay);
        return 1;
    }
    hal_t hal;
    hal_mock_init(&g_mock);
    hal_mock_bind(&g_mock, &hal);
    g_mock.auto_advance_us = 0u;
    g_mock.tx_store = false;
    hal_replay_bind(replay, &hal);

    hd_fw_config_t cfg;
    hd_fw_config_default(&cfg);
    int rc = hd_fw_init(&g_fw, &hal, &cfg);
    if (rc != HD_FW_OK) {
        fprintf(stderr, "target_hostref: firmware init failed: %s\n", hd_fw_err_str(rc));
        fclose(out);
        hal_replay_close(replay);
        return 1;
    }
    uint32_t tick = 0;
    for (;; tick++) {
        g_mock.now_us = (uint64_t)tick * HD_FW_TS_US;
        hd_fw_isr(&g_fw);
        if (g_fw.tick.ended) {
            break;
        }
        (void)hd_fw_background(&g_fw);
        const hd_fw_sample_t *s = hd_fw_last_sample(&g_fw);
        uint8_t rec[28];
        put_le32(&rec[0], tick);
        put_le32(&rec[4], (uint32_t)s->bridge_counts);
        put_le32(&rec[8], float_bits(s->torque_raw_nm));
        put_le32(&rec[12], float_bits(s->torque_filtered_nm));
        put_le32(&rec[16], float_bits(s->ripple_nm));
        put_le32(&rec[20], s->faults);
        put_le32(&rec[24], s->kf_status);
        if (fwrite(rec, 1, sizeof rec, out) != sizeof rec) {
            fprintf(stderr, "target_hostref: write error\n");
            fclose(out);
            hal_replay_close(replay);
            return 1;
        }
    }
    hal_replay_close(replay);
    if (fclose(out) != 0) {
        fprintf(stderr, "target_hostref: write error\n");
        return 1;
    }
    printf("target_hostref: ticks %u\n", (unsigned)tick);
    return 0;
}
