#define _POSIX_C_SOURCE 200809L
/* Replay backend: header checks, record decoding, end of stream, and the ISR
 * fed from a recorded file (torque from counts computed independently). */
#include <stdio.h>
#include <stdlib.h>
#include <string.h>
#include <unistd.h>

#include "hal_mock.h"
#include "hal_replay.h"
#include "hd_calib_record.h"
#include "hd_fw.h"
#include "unity.h"

static char path[64];

void setUp(void)
{
    snprintf(path, sizeof path, "/tmp/test_replay_%d.hdraw", (int)getpid());
}
void tearDown(void)
{
    remove(path);
}

static void put16(uint8_t *p, uint16_t v)
{
    p[0] = (uint8_t)v;
    p[1] = (uint8_t)(v >> 8);
}
static void put32(uint8_t *p, uint32_t v)
{
    for (int i = 0; i < 4; i++) {
        p[i] = (uint8_t)(v >> (8 * i));
    }
}

/* Writes n records: counts = 100 i - 300, motor = 11 i, output = 3 i,
 * flags: record 2 saturated, record 3 encoder fault, all with output. */
static void write_file(const char *magic, uint16_t version, uint32_t ts_us, unsigned n,
                       unsigned trailing)
{
    FILE *f = fopen(path, "wb");
    TEST_ASSERT_NOT_NULL(f);
    uint8_t h[16] = {0};
    memcpy(h, magic, 4);
    put16(&h[4], version);
    put16(&h[6], 16);
    put32(&h[8], ts_us);
    fwrite(h, 1, 16, f);
    for (unsigned i = 0; i < n; i++) {
        uint8_t r[16] = {0};
        put32(&r[0], (uint32_t)(int32_t)(100 * (int)i - 300));
        put32(&r[4], 11u * i);
        put32(&r[8], 3u * i);
        uint16_t flags = 4u | (i == 2 ? 1u : 0u) | (i == 3 ? 2u : 0u);
        put16(&r[12], flags);
        fwrite(r, 1, 16, f);
    }
    for (unsigned i = 0; i < trailing; i++) {
        fputc(0xAB, f);
    }
    fclose(f);
}

static void test_records_are_decoded_in_order(void)
{
    write_file("HDRW", 1, 1000, 5, 0);
    char err[200];
    hal_replay_t *r = hal_replay_open(path, err, sizeof err);
    if (r == NULL) {
        TEST_FAIL_MESSAGE(err);
    }
    TEST_ASSERT_EQUAL_UINT32(1000, hal_replay_ts_us(r));
    TEST_ASSERT_EQUAL_UINT64(5, hal_replay_record_count(r));
    hal_t hal = {0};
    hal_replay_bind(r, &hal);
    for (unsigned i = 0; i < 5; i++) {
        TEST_ASSERT_EQUAL_UINT64((uint64_t)i * 1000u, hal.clock.time_us(hal.clock.ctx));
        hal_adc_sample_t a;
        hal_encoder_sample_t e;
        TEST_ASSERT_EQUAL_INT(HAL_OK, hal.sensors.adc_read(hal.sensors.ctx, &a));
        TEST_ASSERT_EQUAL_INT(HAL_OK, hal.sensors.encoder_read(hal.sensors.ctx, &e));
        TEST_ASSERT_EQUAL_INT32(100 * (int)i - 300, a.bridge_counts);
        TEST_ASSERT_EQUAL_UINT32(11u * i, e.motor_counts);
        TEST_ASSERT_EQUAL_UINT32(3u * i, e.output_counts);
        TEST_ASSERT_TRUE(e.has_output);
        TEST_ASSERT_EQUAL_INT(i == 2, a.saturated);
        TEST_ASSERT_EQUAL_INT(i == 3, e.fault);
    }
    hal_adc_sample_t a;
    TEST_ASSERT_EQUAL_INT(HAL_ERR_END, hal.sensors.adc_read(hal.sensors.ctx, &a));
    hal_replay_close(r);
}

static void test_bad_files_are_refused_with_a_message(void)
{
    char err[200] = "";
    TEST_ASSERT_NULL(hal_replay_open("/nonexistent/x.hdraw", err, sizeof err));
    TEST_ASSERT_TRUE(strstr(err, "cannot open") != NULL);
    write_file("HDRX", 1, 1000, 2, 0);
    TEST_ASSERT_NULL(hal_replay_open(path, err, sizeof err));
    TEST_ASSERT_TRUE(strstr(err, "magic") != NULL);
    write_file("HDRW", 2, 1000, 2, 0);
    TEST_ASSERT_NULL(hal_replay_open(path, err, sizeof err));
    TEST_ASSERT_TRUE(strstr(err, "version") != NULL);
    write_file("HDRW", 1, 0, 2, 0);
    TEST_ASSERT_NULL(hal_replay_open(path, err, sizeof err));
    TEST_ASSERT_TRUE(strstr(err, "ts_us") != NULL);
    FILE *f = fopen(path, "wb");
    fputs("HDRW", f);
    fclose(f);
    TEST_ASSERT_NULL(hal_replay_open(path, err, sizeof err));
    TEST_ASSERT_TRUE(strstr(err, "header") != NULL);
    /* a trailing partial record is reported and ignored */
    write_file("HDRW", 1, 1000, 3, 7);
    hal_replay_t *r = hal_replay_open(path, err, sizeof err);
    TEST_ASSERT_NOT_NULL(r);
    TEST_ASSERT_EQUAL_UINT64(3, hal_replay_record_count(r));
    TEST_ASSERT_EQUAL_UINT32(7, hal_replay_trailing_bytes(r));
    hal_replay_close(r);
}

static void test_isr_runs_from_a_recording(void)
{
    write_file("HDRW", 1, 1000, 6, 0);
    char err[200];
    hal_replay_t *r = hal_replay_open(path, err, sizeof err);
    TEST_ASSERT_NOT_NULL(r);
    static hal_mock_t mock; /* CAN and NVM from the mock */
    hal_t hal;
    hal_mock_init(&mock);
    hal_mock_bind(&mock, &hal);
    hal_replay_bind(r, &hal);
    hd_calib_record_t rec;
    hd_calib_record_default(&rec);
    rec.gain_nm_per_v = 5.0f;
    rec.offset_v = 0.0f;
    static uint8_t work[HD_STORE_IMAGE_MAX];
    hd_calib_storage_t s = hd_fw_store_io(&hal, work, sizeof work);
    TEST_ASSERT_EQUAL_INT(HD_RECORD_OK, hd_calib_store_save(&s, &rec));
    hd_fw_config_t cfg;
    hd_fw_config_default(&cfg);
    cfg.filter_enabled = 0;
    static hd_fw_t fw;
    TEST_ASSERT_EQUAL_INT(HD_FW_OK, hd_fw_init(&fw, &hal, &cfg));
    unsigned ticks = 0;
    for (; ticks < 10 && !fw.tick.ended; ticks++) {
        hd_fw_isr(&fw);
        const hd_fw_sample_t *smp = hd_fw_last_sample(&fw);
        if (fw.tick.ended) {
            break;
        }
        if (ticks == 2) {
            TEST_ASSERT_TRUE((smp->faults & HD_FAULT_ADC_SATURATED) != 0u);
        } else if (ticks == 3) {
            TEST_ASSERT_TRUE((smp->faults & HD_FAULT_ENC_FAULT) != 0u);
        } else {
            double expect = 5.0 * (100.0 * ticks - 300.0) * (10.0 / 32768.0);
            TEST_ASSERT_FLOAT_WITHIN(1e-4, expect, smp->torque_raw_nm);
        }
        TEST_ASSERT_EQUAL_UINT64((uint64_t)ticks * 1000u, smp->t_us);
    }
    TEST_ASSERT_TRUE(fw.tick.ended);
    TEST_ASSERT_EQUAL_UINT(6, ticks);
    TEST_ASSERT_EQUAL_UINT32(6, hd_fw_counters(&fw)->ticks);
    TEST_ASSERT_EQUAL_UINT32(0, hd_fw_counters(&fw)->deadline_misses);
    hal_replay_close(r);
}

int main(int argc, char **argv)
{
    if (UnityParseOptions(argc, argv) != 0) {
        return 1;
    }
    UNITY_BEGIN();
    RUN_TEST(test_records_are_decoded_in_order);
    RUN_TEST(test_bad_files_are_refused_with_a_message);
    RUN_TEST(test_isr_runs_from_a_recording);
    return UNITY_END();
}
