/* fw_replay_dump CONFIG.txt LOG.csv OUT.bin: the firmware (hd_fw on the
 * mock HAL, as the host build runs it) fed a sensor log, and what its tick
 * gave the filter and got back, as float32 bits, for test_pipeline_replay.py
 * to replay through the analysis (cfilter -> hd_pipeline_run).
 *
 * LOG.csv: a header line, then per tick
 *   bridge_counts,motor_counts,output_counts,motor_current_a,feedforward_nm
 * (feedforward_nm nan: no FEEDFORWARD frame this tick).
 * OUT.bin (little-endian): "HDRD", u32 ticks, u32 sizeof(hd_kf_config_t),
 * the live filter's hd_kf_config_t, hd_expected_config_t, f32 track
 * bandwidth, then per tick 8 f32: torque_raw_nm, d_motor_angle_rad,
 * d_output_angle_rad, feedforward_nm, motor_current_a, torque_filtered_nm,
 * torque_expected_nm, torque_expected_var_nm2.  Exit 0, or 1 with one line
 * on stderr. */
#define _POSIX_C_SOURCE 200809L
#include <math.h>
#include <stdio.h>
#include <stdlib.h>
#include <string.h>

#include "hal_mock.h"
#include "hd_config_text.h"
#include "hd_fw.h"

static hal_mock_t g_mock;
static hal_t g_hal;
static hd_fw_t g_fw;

static int fail(const char *what)
{
    fprintf(stderr, "fw_replay_dump: %s\n", what);
    return 1;
}

static int load_config(const char *path, hd_fw_config_t *cfg)
{
    static char text[HD_CFGTXT_MAX_BYTES];
    FILE *f = fopen(path, "rb");
    if (f == NULL) {
        return -1;
    }
    const size_t n = fread(text, 1, sizeof text, f);
    fclose(f);
    hd_fw_config_default(cfg);
    return hd_config_text_parse(text, n, cfg, NULL) == HD_FW_OK ? 0 : -1;
}

static void put_feedforward(float nm, uint8_t seq)
{
    const hd_can_feedforward_t ff = {nm, seq};
    hal_can_frame_t f;
    hd_can_encode_feedforward(hd_fw_config(&g_fw)->node_id, &ff, &f);
    (void)hal_mock_push_rx(&g_mock, &f);
}

static void put_tick(FILE *out, const hd_fw_sample_t *s)
{
    const float v[8] = {s->torque_raw_nm,     s->d_motor_angle_rad,  s->d_output_angle_rad,
                        s->feedforward_nm,    s->motor_current_a,    s->torque_filtered_nm,
                        s->torque_expected_nm, s->torque_expected_var_nm2};
    fwrite(v, sizeof v, 1, out);
}

static int run(FILE *log, FILE *out)
{
    char line[256];
    if (fgets(line, sizeof line, log) == NULL) {
        return -1; /* no header */
    }
    uint32_t ticks = 0u;
    uint8_t seq = 0u;
    long counts;
    unsigned long motor, output;
    float cur, ff;
    while (fscanf(log, "%ld,%lu,%lu,%f,%f", &counts, &motor, &output, &cur, &ff) == 5) {
        hal_mock_sample_t smp;
        memset(&smp, 0, sizeof smp);
        smp.adc.bridge_counts = (int32_t)counts;
        smp.enc.motor_counts = (uint32_t)motor;
        smp.enc.output_counts = (uint32_t)output;
        smp.enc.has_output = true;
        smp.cur.motor_current_a = cur;
        if (isfinite(ff)) {
            put_feedforward(ff, seq++);
        }
        if (hal_mock_push_sample(&g_mock, &smp) != 0) {
            return -1;
        }
        hd_fw_isr(&g_fw);
        hd_fw_background(&g_fw);
        put_tick(out, hd_fw_last_sample(&g_fw));
        ticks++;
    }
    return (int)ticks;
}

int main(int argc, char **argv)
{
    if (argc != 4) {
        return fail("usage: fw_replay_dump CONFIG.txt LOG.csv OUT.bin");
    }
    hd_fw_config_t cfg;
    if (load_config(argv[1], &cfg) != 0) {
        return fail("configuration refused");
    }
    hal_mock_init(&g_mock);
    g_mock.current_channel = true;
    g_mock.tx_store = false;
    hal_mock_bind(&g_mock, &g_hal);
    if (hd_fw_init(&g_fw, &g_hal, &cfg) != HD_FW_OK) {
        return fail("hd_fw_init failed");
    }
    FILE *log = fopen(argv[2], "r");
    FILE *out = fopen(argv[3], "wb");
    if (log == NULL || out == NULL) {
        return fail("cannot open the log or the output");
    }
    const hd_pipeline_t *p = &g_fw.pipe[g_fw.live_pipe & 1u];
    const float bw = cfg.track_bandwidth_hz;
    const uint32_t head[3] = {0x44524448u, 0u, (uint32_t)sizeof p->kf.cfg};
    fwrite(head, sizeof head, 1, out);
    fwrite(&p->kf.cfg, sizeof p->kf.cfg, 1, out);
    fwrite(&p->expected, sizeof p->expected, 1, out);
    fwrite(&bw, sizeof bw, 1, out);
    const int ticks = run(log, out);
    fclose(log);
    if (ticks <= 0) {
        fclose(out);
        return fail("no ticks read from the log");
    }
    const uint32_t n = (uint32_t)ticks;
    fseek(out, 4, SEEK_SET);
    fwrite(&n, sizeof n, 1, out);
    return fclose(out) == 0 ? 0 : fail("write failed");
}
