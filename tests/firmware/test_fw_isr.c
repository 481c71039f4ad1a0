/* The ISR on the mock HAL: injected samples -> telemetry frames whose scaled
 * values are computed here independently (double precision), sequence
 * counter, rate divider, heartbeat, fault flags, calibration record
 * handling, and commands (good, bad, malformed: error ACK, nothing changed). */
#include <math.h>
#include <stdlib.h>
#include <string.h>

#include "hal_mock.h"
#include "hd_calib_record.h"
#include "hd_fw.h"
#include "unity.h"

static hal_mock_t mock;
static hal_t hal;
static hd_fw_t fw;
static hd_fw_config_t cfg;

#define GAIN 6.6
#define OFFSET_V 0.1
#define VPC (10.0 / 32768.0)
#define CPR 4096u
#define TEST_PI 3.14159265358979323846

static hd_calib_storage_t storage(void)
{
    hd_calib_storage_t s = {hal.nvm.ctx, hal.nvm.size, hal.nvm.read, hal.nvm.write, hal.nvm.erase};
    return s;
}

static void store_calibration(float gain, float offset)
{
    hd_calib_record_t rec;
    hd_calib_record_default(&rec);
    rec.gain_nm_per_v = gain;
    rec.offset_v = offset;
    hd_calib_storage_t s = storage();
    TEST_ASSERT_EQUAL_INT(0, hd_calib_store_save(&s, &rec));
}

void setUp(void)
{
    hal_mock_init(&mock);
    hal_mock_bind(&mock, &hal);
    hd_fw_config_default(&cfg);
    cfg.motor_cpr = CPR;
    cfg.adc_volts_per_count = (float)VPC;
    cfg.filter_enabled = 0; /* raw = filtered: exact expectations */
    store_calibration((float)GAIN, (float)OFFSET_V);
}
void tearDown(void) {}

static void init_fw(void)
{
    TEST_ASSERT_EQUAL_INT(HD_FW_OK, hd_fw_init(&fw, &hal, &cfg));
}

/* Runs n ticks with constant counts and a motor moving step counts per tick. */
static uint32_t motor = 0;
static void run(unsigned n, int32_t counts, uint32_t step)
{
    for (unsigned i = 0; i < n; i++) {
        motor += step;
        TEST_ASSERT_EQUAL_INT(0, hal_mock_push(&mock, counts, motor));
        hd_fw_isr(&fw);
    }
}

/* Telemetry A frames (id 0x100 + node) in the mock's transmit log. */
static unsigned count_id(uint32_t id)
{
    unsigned n = 0;
    for (uint32_t i = 0; i < hal_mock_tx_count(&mock); i++) {
        n += hal_mock_tx(&mock, i)->id == id;
    }
    return n;
}

/* Counts every transmitted frame by id, beyond the mock's storage. */
static unsigned id_counts[0x800];
static void count_hook(void *ctx, const hal_can_frame_t *f, uint64_t t_us)
{
    (void)ctx;
    (void)t_us;
    id_counts[f->id & 0x7FFu]++;
}

static const hal_can_frame_t *last_id(uint32_t id)
{
    const hal_can_frame_t *f = NULL;
    for (uint32_t i = 0; i < hal_mock_tx_count(&mock); i++) {
        if (hal_mock_tx(&mock, i)->id == id) {
            f = hal_mock_tx(&mock, i);
        }
    }
    return f;
}

static int16_t i16_at(const hal_can_frame_t *f, unsigned byte)
{
    return (int16_t)(uint16_t)(f->data[byte] | (f->data[byte + 1] << 8));
}

static void test_telemetry_scaled_values_and_sequence(void)
{
    init_fw();
    const int32_t counts = 5000;
    run(10, counts, 7);
    /* independent expectation: 6.6 * (5000 * 10/32768 - 0.1) = 9.41103... Nm */
    double torque = GAIN * (counts * VPC - OFFSET_V);
    long lsb = lround(torque / 0.01);
    TEST_ASSERT_EQUAL_UINT(10, count_id(0x101));
    TEST_ASSERT_EQUAL_UINT(10, count_id(0x181));
    TEST_ASSERT_EQUAL_UINT(1, count_id(0x701)); /* heartbeat on tick 0 only */
    unsigned seq = 0;
    for (uint32_t i = 0; i < hal_mock_tx_count(&mock); i++) {
        const hal_can_frame_t *f = hal_mock_tx(&mock, i);
        if (f->id == 0x101) {
            TEST_ASSERT_EQUAL_UINT8(8, f->len);
            TEST_ASSERT_EQUAL_INT(lsb, i16_at(f, 2)); /* raw */
            TEST_ASSERT_EQUAL_INT(lsb, i16_at(f, 0)); /* filter off: filtered = raw */
            TEST_ASSERT_EQUAL_UINT8(seq, f->data[6]);
            const hal_can_frame_t *b = hal_mock_tx(&mock, i + 1);
            TEST_ASSERT_EQUAL_HEX32(0x181, b->id); /* B follows A with the same seq */
            TEST_ASSERT_EQUAL_UINT8(seq, b->data[7]);
            TEST_ASSERT_EQUAL_UINT16(0, (uint16_t)(b->data[4] | (b->data[5] << 8)));
            seq++;
        }
    }
    const hd_fw_sample_t *s = hd_fw_last_sample(&fw);
    TEST_ASSERT_TRUE(s->valid);
    TEST_ASSERT_FLOAT_WITHIN(1e-4, torque, s->torque_raw_nm);
    TEST_ASSERT_FLOAT_WITHIN(1e-6, 7.0 * 2.0 * TEST_PI / CPR, s->d_motor_angle_rad);
    /* no output encoder: output increment = motor increment / gear ratio */
    TEST_ASSERT_FLOAT_WITHIN(1e-8, 7.0 * 2.0 * TEST_PI / CPR / 100.0, s->d_output_angle_rad);
}

static void test_rate_divider_and_heartbeat_period(void)
{
    cfg.telemetry_rate_hz = 250; /* every 4th tick */
    init_fw();
    memset(id_counts, 0, sizeof id_counts);
    mock.tx_store = false;
    mock.tx_hook = count_hook;
    run(2001, 0, 1);
    TEST_ASSERT_EQUAL_UINT(501, id_counts[0x101]); /* ticks 0, 4, ..., 2000 */
    TEST_ASSERT_EQUAL_UINT(501, id_counts[0x181]);
    TEST_ASSERT_EQUAL_UINT(3, id_counts[0x701]);   /* ticks 0, 1000, 2000 */
    mock.tx_store = true;
    mock.tx_hook = NULL;
    run(3, 0, 1);
    run(1, 0, 1); /* tick 2004: sent and stored */
    const hal_can_frame_t *a = last_id(0x101);
    TEST_ASSERT_EQUAL_UINT8(501 % 256, a->data[6]); /* sequence wraps modulo 256 */
    cfg.telemetry_rate_hz = 0; /* off */
    hal_mock_init(&mock);
    hal_mock_bind(&mock, &hal);
    store_calibration((float)GAIN, (float)OFFSET_V);
    init_fw();
    run(50, 0, 1);
    TEST_ASSERT_EQUAL_UINT(0, count_id(0x101));
}

static uint16_t last_faults(void)
{
    const hal_can_frame_t *b = last_id(0x181);
    TEST_ASSERT_NOT_NULL(b);
    return (uint16_t)(b->data[4] | (b->data[5] << 8));
}

static void push_special(int adc_rc, bool saturated, int32_t counts)
{
    hal_mock_sample_t s;
    memset(&s, 0, sizeof s);
    s.adc_rc = adc_rc;
    s.adc.saturated = saturated;
    s.adc.bridge_counts = counts;
    motor += 3;
    s.enc.motor_counts = motor;
    hal_mock_push_sample(&mock, &s);
    hd_fw_isr(&fw);
}

static void test_invalid_samples_are_flagged_and_not_sent_as_torque(void)
{
    init_fw();
    run(5, 100, 3);
    push_special(HAL_OK, true, 32767);
    TEST_ASSERT_EQUAL_HEX16(HD_FAULT_ADC_SATURATED, last_faults());
    TEST_ASSERT_EQUAL_INT(INT16_MIN, i16_at(last_id(0x101), 0));
    TEST_ASSERT_EQUAL_INT(INT16_MIN, i16_at(last_id(0x101), 2));
    TEST_ASSERT_FALSE(hd_fw_last_sample(&fw)->valid);
    push_special(HAL_ERR_FAULT, false, 0);
    TEST_ASSERT_EQUAL_HEX16(HD_FAULT_OPEN_BRIDGE, last_faults());
    push_special(HAL_ERR_IO, false, 0);
    TEST_ASSERT_EQUAL_HEX16(HD_FAULT_ADC_ERROR, last_faults());
    /* 30000 counts = 9.155 V -> 59.8 Nm: above a 50 Nm limit */
    fw.cfg.torque_limit_nm = 50.0f;
    push_special(HAL_OK, false, 30000);
    TEST_ASSERT_EQUAL_HEX16(HD_FAULT_TORQUE_RANGE, last_faults());
    run(1, 100, 3);
    TEST_ASSERT_EQUAL_HEX16(0, last_faults());
    const hd_fw_counters_t *c = hd_fw_counters(&fw);
    TEST_ASSERT_EQUAL_UINT32(1, c->by_fault[1]);
    TEST_ASSERT_EQUAL_UINT32(1, c->by_fault[2]);
    TEST_ASSERT_EQUAL_UINT32(1, c->by_fault[0]);
    TEST_ASSERT_EQUAL_UINT32(1, c->by_fault[3]);
    TEST_ASSERT_EQUAL_UINT32(4, c->fault_ticks);
    TEST_ASSERT_EQUAL_UINT32(6, c->valid_samples);
}

static void test_faults_survive_decimation(void)
{
    cfg.telemetry_rate_hz = 100; /* every 10th tick */
    init_fw();
    run(3, 100, 3);                /* tick 0 sent, 1, 2 not */
    push_special(HAL_OK, true, 0); /* tick 3: not a telemetry tick */
    run(6, 100, 3);                /* ticks 4..9 */
    TEST_ASSERT_EQUAL_UINT(1, count_id(0x101));
    run(1, 100, 3);                /* tick 10: telemetry carries the saturation */
    TEST_ASSERT_EQUAL_HEX16(HD_FAULT_ADC_SATURATED, last_faults());
    run(10, 100, 3);
    TEST_ASSERT_EQUAL_HEX16(0, last_faults());
}

static void test_encoder_glitch_is_ignored_and_flagged(void)
{
    init_fw();
    run(10, 0, 20);
    /* one-sample spike of +100000 counts (impossible at 1000 rad/s: 652 max) */
    motor += 20;
    hal_mock_push(&mock, 0, motor + 100000u);
    hd_fw_isr(&fw);
    TEST_ASSERT_EQUAL_HEX16(HD_FAULT_ENC_GLITCH, hd_fw_last_sample(&fw)->faults);
    double step_rad = 20.0 * 2.0 * TEST_PI / CPR;
    TEST_ASSERT_FLOAT_WITHIN(1e-6, step_rad, hd_fw_last_sample(&fw)->d_motor_angle_rad);
    run(1, 0, 20); /* back to the true count: the reverse jump is a glitch too */
    TEST_ASSERT_EQUAL_HEX16(HD_FAULT_ENC_GLITCH, hd_fw_last_sample(&fw)->faults);
    TEST_ASSERT_FLOAT_WITHIN(1e-6, step_rad, hd_fw_last_sample(&fw)->d_motor_angle_rad);
    run(1, 0, 20);
    TEST_ASSERT_EQUAL_HEX16(0, hd_fw_last_sample(&fw)->faults);
    TEST_ASSERT_FLOAT_WITHIN(1e-6, step_rad, hd_fw_last_sample(&fw)->d_motor_angle_rad);
    TEST_ASSERT_EQUAL_UINT32(2, hd_fw_counters(&fw)->by_fault[4]);
    /* wrap of the 32-bit counter is not a glitch */
    motor = 0xFFFFFFF0u;
    init_fw();
    run(3, 0, 20);
    TEST_ASSERT_EQUAL_UINT32(0, hd_fw_counters(&fw)->by_fault[4]);
    TEST_ASSERT_FLOAT_WITHIN(1e-6, step_rad, hd_fw_last_sample(&fw)->d_motor_angle_rad);
}

static void test_encoder_fault_uses_the_previous_motion(void)
{
    init_fw();
    run(5, 0, 10);
    hal_mock_sample_t s;
    memset(&s, 0, sizeof s);
    s.enc.fault = true;
    hal_mock_push_sample(&mock, &s);
    hd_fw_isr(&fw);
    TEST_ASSERT_EQUAL_HEX16(HD_FAULT_ENC_FAULT, hd_fw_last_sample(&fw)->faults);
    TEST_ASSERT_FLOAT_WITHIN(1e-6, 10.0 * 2.0 * TEST_PI / CPR, hd_fw_last_sample(&fw)->d_motor_angle_rad);
    motor += 10; /* the motor really moved during the faulty tick */
    run(1, 0, 10);
    TEST_ASSERT_EQUAL_HEX16(0, hd_fw_last_sample(&fw)->faults);
}

static void test_nyquist_frozen_block_is_flagged(void)
{
    init_fw();
    /* 480 counts/tick = 0.736 rad/tick: motor order 4 advances 2.95 rad > 0.9 pi */
    run(5, 0, 480);
    TEST_ASSERT_TRUE((hd_fw_last_sample(&fw)->faults & HD_FAULT_KF_FROZEN) != 0u);
    TEST_ASSERT_TRUE((last_faults() & HD_FAULT_KF_FROZEN) != 0u);
}

static void test_can_tx_full_and_bus_off_are_flagged(void)
{
    init_fw();
    run(2, 0, 1);
    mock.tx_budget = 0;
    run(1, 0, 1); /* both telemetry frames refused */
    mock.tx_budget = -1;
    run(1, 0, 1);
    TEST_ASSERT_TRUE((last_faults() & HD_FAULT_CAN_TX_FULL) != 0u);
    mock.bus_off = true;
    run(1, 0, 1);
    mock.bus_off = false;
    run(1, 0, 1);
    TEST_ASSERT_TRUE((last_faults() & HD_FAULT_CAN_BUS_OFF) != 0u);
    TEST_ASSERT_EQUAL_UINT32(4, mock.counters.can_tx_dropped);
}

static void test_missing_calibration_uses_defaults_and_flags(void)
{
    memset(mock.nvm, 0xFF, sizeof mock.nvm); /* blank */
    init_fw();
    run(3, 1000, 1);
    TEST_ASSERT_EQUAL_INT(HD_CALIB_LOAD_MISSING, fw.calib_load_result);
    TEST_ASSERT_EQUAL_HEX16(HD_FAULT_CALIB_MISSING, last_faults());
    /* defaults (nominal 6.60 Nm/V, offset 0) are used, visibly */
    TEST_ASSERT_FLOAT_WITHIN(1e-4, 6.60 * 1000 * VPC, hd_fw_last_sample(&fw)->torque_raw_nm);
    const hal_can_frame_t *hb = last_id(0x701);
    TEST_ASSERT_EQUAL_UINT8(2, hb->data[7]); /* CalibStatus MISSING */
    TEST_ASSERT_EQUAL_UINT8(HD_STATE_DEGRADED, hb->data[0]);

    /* corrupt: flip a byte inside both copies */
    hal_mock_init(&mock);
    hal_mock_bind(&mock, &hal);
    store_calibration(7.0f, 0.2f);
    for (unsigned i = 0; i < sizeof mock.nvm; i += 64) {
        mock.nvm[i + 10] ^= 0x5Au;
    }
    init_fw();
    run(2, 1000, 1);
    TEST_ASSERT_TRUE(fw.calib_load_result < 0);
    TEST_ASSERT_TRUE((last_faults() & HD_FAULT_CALIB_CORRUPT) != 0u);
    TEST_ASSERT_FLOAT_WITHIN(1e-4, 6.60 * 1000 * VPC, hd_fw_last_sample(&fw)->torque_raw_nm);

    /* NVM I/O error */
    mock.nvm_fail = true;
    init_fw();
    run(1, 0, 1);
    TEST_ASSERT_TRUE((last_faults() & HD_FAULT_CALIB_CORRUPT) != 0u);
}

/* ------------------------------------------------------------- commands */

static hd_can_ack_t send_cmd(const hd_can_cmd_t *c)
{
    hal_can_frame_t f;
    hd_can_encode_cmd(fw.cfg.node_id, c, &f);
    uint32_t before = hal_mock_tx_count(&mock);
    hal_mock_push_rx(&mock, &f);
    run(1, 1000, 1);
    hd_fw_background(&fw);
    hd_can_ack_t a;
    memset(&a, 0xEE, sizeof a);
    for (uint32_t i = before; i < hal_mock_tx_count(&mock); i++) {
        const hal_can_frame_t *t = hal_mock_tx(&mock, i);
        if (t->id >= HD_CAN_ID_ACK && t->id <= HD_CAN_ID_ACK + 127u) {
            hd_can_decode_ack(t, &a);
        }
    }
    return a;
}

static hd_can_ack_t set_param(int id, float v)
{
    hd_can_cmd_t c = {0};
    c.opcode = HD_CMD_SET_PARAM;
    c.token = 0x33;
    c.arg_u8[0] = (uint8_t)id;
    c.value = v;
    return send_cmd(&c);
}

static void test_set_and_get_parameters(void)
{
    init_fw();
    hd_can_ack_t a = set_param(HD_PARAM_R_NM2, 0.5f);
    TEST_ASSERT_EQUAL_UINT8(HD_CAN_RES_OK, a.result);
    TEST_ASSERT_EQUAL_UINT8(HD_CMD_SET_PARAM, a.opcode);
    TEST_ASSERT_EQUAL_UINT8(0x33, a.token);
    TEST_ASSERT_EQUAL_FLOAT(0.5f, a.value);
    TEST_ASSERT_EQUAL_FLOAT(0.5f, fw.pipe.kf.cfg.r_nm2); /* the running filter uses it */
    hd_can_cmd_t g = {0};
    g.opcode = HD_CMD_GET_PARAM;
    g.arg_u8[0] = HD_PARAM_R_NM2;
    a = send_cmd(&g);
    TEST_ASSERT_EQUAL_UINT8(HD_CAN_RES_OK, a.result);
    TEST_ASSERT_EQUAL_FLOAT(0.5f, a.value);
    TEST_ASSERT_EQUAL_UINT8(HD_CAN_RES_OK, set_param(HD_PARAM_GEAR_RATIO, 50.0f).result);
    TEST_ASSERT_EQUAL_FLOAT(50.0f, fw.cfg.gear_ratio);
    TEST_ASSERT_EQUAL_UINT8(HD_CAN_RES_OK, set_param(HD_PARAM_INERTIA_KGM2, 0.02f).result);
    TEST_ASSERT_EQUAL_FLOAT(0.02f, fw.pipe.expected.inertia_kgm2);
    TEST_ASSERT_EQUAL_UINT8(HD_CAN_RES_OK, set_param(HD_PARAM_CALIB_GAIN_NM_PER_V, 7.0f).result);
    run(1, 1000, 1);
    TEST_ASSERT_FLOAT_WITHIN(1e-4, 7.0 * (1000 * VPC - OFFSET_V), hd_fw_last_sample(&fw)->torque_raw_nm);
}

static void test_rejected_commands_change_nothing(void)
{
    init_fw();
    const struct {
        int id;
        float v;
        int res;
    } bad[] = {
        {HD_PARAM_R_NM2, -1.0f, HD_CAN_RES_OUT_OF_RANGE},
        {HD_PARAM_R_NM2, 0.0f, HD_CAN_RES_OUT_OF_RANGE},
        {HD_PARAM_GEAR_RATIO, 0.5f, HD_CAN_RES_OUT_OF_RANGE},
        {HD_PARAM_TELEMETRY_RATE_HZ, 1500.0f, HD_CAN_RES_OUT_OF_RANGE},
        {HD_PARAM_TELEMETRY_RATE_HZ, 2.5f, HD_CAN_RES_OUT_OF_RANGE},
        {HD_PARAM_NODE_ID, 0.0f, HD_CAN_RES_OUT_OF_RANGE},
        {HD_PARAM_NODE_ID, 128.0f, HD_CAN_RES_OUT_OF_RANGE},
        {HD_PARAM_OFFSET_ENABLED, 2.0f, HD_CAN_RES_OUT_OF_RANGE},
        {HD_PARAM_TRACK_BANDWIDTH_HZ, 500.0f, HD_CAN_RES_OUT_OF_RANGE},
        {HD_PARAM_BLOCK_COUNT, 1.0f, HD_CAN_RES_READ_ONLY},
        {HD_PARAM_CALIB_GAIN_NM_PER_V, -2.0f, HD_CAN_RES_OUT_OF_RANGE},
        {0, 1.0f, HD_CAN_RES_UNKNOWN_PARAM},
        {200, 1.0f, HD_CAN_RES_UNKNOWN_PARAM},
    };
    for (unsigned i = 0; i < sizeof bad / sizeof bad[0]; i++) {
        hd_fw_config_t before_cfg = fw.cfg;
        hd_calib_record_t before_cal = fw.calib;
        hd_can_ack_t a = set_param(bad[i].id, bad[i].v);
        TEST_ASSERT_EQUAL_UINT8(bad[i].res, a.result);
        TEST_ASSERT_EQUAL_MEMORY(&before_cfg, &fw.cfg, sizeof before_cfg);
        TEST_ASSERT_EQUAL_MEMORY(&before_cal, &fw.calib, sizeof before_cal);
    }
    TEST_ASSERT_TRUE((last_faults() & HD_FAULT_CMD_ERROR) != 0u);
    TEST_ASSERT_EQUAL_UINT32(13, hd_fw_counters(&fw)->command_errors);

    /* malformed frames on the command id: error ACK, nothing changed */
    hd_fw_config_t before_cfg = fw.cfg;
    hal_can_frame_t f = {0};
    f.id = 0x601;
    f.len = 3;
    f.data[0] = HD_CMD_SET_PARAM;
    f.data[1] = 5;
    uint32_t n0 = hal_mock_tx_count(&mock);
    hal_mock_push_rx(&mock, &f);
    f.len = 8;
    f.data[0] = 0x77; /* unknown opcode */
    hal_mock_push_rx(&mock, &f);
    f.data[0] = HD_CMD_SET_PARAM;
    f.flags = HAL_CAN_FLAG_RTR;
    hal_mock_push_rx(&mock, &f);
    f.flags = 0;
    f.id = 0x602; /* another node: ignored, no reply */
    hal_mock_push_rx(&mock, &f);
    run(1, 1000, 1);
    int results[3];
    unsigned n = 0;
    for (uint32_t i = n0; i < hal_mock_tx_count(&mock); i++) {
        const hal_can_frame_t *t = hal_mock_tx(&mock, i);
        TEST_ASSERT_TRUE(t->id != 0x582u);
        if (t->id == 0x581u && n < 3) {
            results[n++] = t->data[2];
        }
    }
    TEST_ASSERT_EQUAL_UINT(3, n);
    TEST_ASSERT_EQUAL_INT(HD_CAN_RES_BAD_LENGTH, results[0]);
    TEST_ASSERT_EQUAL_INT(HD_CAN_RES_UNKNOWN_OPCODE, results[1]);
    TEST_ASSERT_EQUAL_INT(HD_CAN_RES_BAD_FRAME, results[2]);
    TEST_ASSERT_EQUAL_MEMORY(&before_cfg, &fw.cfg, sizeof before_cfg);
}

static void test_filter_blocks_by_command(void)
{
    init_fw();
    unsigned n0 = fw.cfg.kf.block_count;
    hd_can_cmd_t c = {0};
    c.opcode = HD_CMD_ADD_FIXED;
    c.order = 50.0f;
    c.value = 1e-4f;
    hd_can_ack_t a = send_cmd(&c);
    TEST_ASSERT_EQUAL_UINT8(HD_CAN_RES_OK, a.result);
    TEST_ASSERT_EQUAL_UINT8(n0, a.aux);
    TEST_ASSERT_EQUAL_UINT8(n0 + 1, fw.cfg.kf.block_count);
    TEST_ASSERT_EQUAL_UINT8(HD_KF_LOCK_FIXED, fw.cfg.kf.blocks[n0].lock);
    TEST_ASSERT_EQUAL_FLOAT(50.0f, fw.cfg.kf.blocks[n0].order);
    c.order = 600.0f; /* over Nyquist */
    TEST_ASSERT_EQUAL_UINT8(HD_CAN_RES_OUT_OF_RANGE, send_cmd(&c).result);
    c.opcode = HD_CMD_ADD_MOTOR;
    c.order = 6.0f;
    while (fw.cfg.kf.block_count < HD_KF_MAX_BLOCKS) {
        TEST_ASSERT_EQUAL_UINT8(HD_CAN_RES_OK, send_cmd(&c).result);
    }
    hd_fw_config_t before = fw.cfg;
    TEST_ASSERT_EQUAL_UINT8(HD_CAN_RES_NO_SPACE, send_cmd(&c).result);
    TEST_ASSERT_EQUAL_MEMORY(&before, &fw.cfg, sizeof before);

    hd_can_cmd_t e = {0};
    e.opcode = HD_CMD_BLOCK_ENABLE;
    e.arg_u8[0] = 1;
    e.arg_u8[1] = 0;
    TEST_ASSERT_EQUAL_UINT8(HD_CAN_RES_OK, send_cmd(&e).result);
    TEST_ASSERT_EQUAL_UINT8(0, fw.cfg.kf.blocks[1].enabled);
    e.arg_u8[0] = 8;
    TEST_ASSERT_EQUAL_UINT8(HD_CAN_RES_BAD_INDEX, send_cmd(&e).result);

    hd_can_cmd_t clr = {0};
    clr.opcode = HD_CMD_BLOCKS_CLEAR;
    TEST_ASSERT_EQUAL_UINT8(HD_CAN_RES_OK, send_cmd(&clr).result);
    TEST_ASSERT_EQUAL_UINT8(0, fw.cfg.kf.block_count);
}

static void test_node_id_telemetry_rate_and_tare(void)
{
    init_fw();
    hd_can_ack_t a = set_param(HD_PARAM_NODE_ID, 5.0f);
    TEST_ASSERT_EQUAL_UINT8(HD_CAN_RES_OK, a.result);
    TEST_ASSERT_NOT_NULL(last_id(0x581)); /* ACK from the old id */
    hal_mock_tx_clear(&mock);
    run(1, 1000, 1);
    TEST_ASSERT_EQUAL_UINT(1, count_id(0x105));
    TEST_ASSERT_EQUAL_UINT(0, count_id(0x101));

    TEST_ASSERT_EQUAL_UINT8(HD_CAN_RES_OK, set_param(HD_PARAM_TELEMETRY_RATE_HZ, 100.0f).result);
    hal_mock_tx_clear(&mock);
    run(100, 1000, 1);
    TEST_ASSERT_EQUAL_UINT(10, count_id(0x105));

    /* tare: constant 1000 counts -> offset_v = 1000 * VPC, torque -> 0 */
    run(64, 1000, 1);
    hd_can_cmd_t t = {0};
    t.opcode = HD_CMD_TARE;
    a = send_cmd(&t);
    TEST_ASSERT_EQUAL_UINT8(HD_CAN_RES_OK, a.result);
    TEST_ASSERT_FLOAT_WITHIN(1e-6, 1000 * VPC, a.value);
    run(1, 1000, 1);
    TEST_ASSERT_FLOAT_WITHIN(1e-4, 0.0, hd_fw_last_sample(&fw)->torque_raw_nm);
}

static void test_tare_without_samples_is_refused(void)
{
    init_fw();
    hal_can_frame_t f;
    hd_can_cmd_t t = {0};
    t.opcode = HD_CMD_TARE;
    hd_can_encode_cmd(1, &t, &f);
    hd_fw_handle_frame(&fw, &f); /* before any tick */
    hd_can_ack_t a;
    TEST_ASSERT_EQUAL_INT(0, hd_can_decode_ack(last_id(0x581), &a));
    TEST_ASSERT_EQUAL_UINT8(HD_CAN_RES_NO_DATA, a.result);
    TEST_ASSERT_EQUAL_FLOAT((float)OFFSET_V, fw.calib.offset_v);
}

static void test_calibration_save_and_load_by_command(void)
{
    memset(mock.nvm, 0xFF, sizeof mock.nvm); /* start without a record */
    init_fw();
    TEST_ASSERT_EQUAL_UINT8(HD_CAN_RES_OK, set_param(HD_PARAM_CALIB_GAIN_NM_PER_V, 6.5f).result);
    TEST_ASSERT_EQUAL_UINT8(HD_CAN_RES_OK, set_param(HD_PARAM_CALIB_OFFSET_V, -0.05f).result);
    hd_can_cmd_t c = {0};
    c.opcode = HD_CMD_CALIB_SAVE;
    c.token = 9;
    c.arg_u32 = 1700000000u;
    hd_can_ack_t a = send_cmd(&c); /* send_cmd runs hd_fw_background */
    TEST_ASSERT_EQUAL_UINT8(HD_CAN_RES_OK, a.result);
    TEST_ASSERT_EQUAL_UINT8(HD_CMD_CALIB_SAVE, a.opcode);
    TEST_ASSERT_EQUAL_UINT8(9, a.token);
    /* read back independently of the firmware */
    hd_calib_storage_t s = storage();
    hd_calib_record_t rec;
    uint32_t seq;
    TEST_ASSERT_TRUE(hd_calib_store_load(&s, &rec, &seq) >= 0);
    TEST_ASSERT_EQUAL_FLOAT(6.5f, rec.gain_nm_per_v);
    TEST_ASSERT_EQUAL_FLOAT(-0.05f, rec.offset_v);
    TEST_ASSERT_EQUAL_UINT32(1700000000u, rec.calibrated_unix_s);
    run(1, 0, 1);
    TEST_ASSERT_EQUAL_HEX16(0, last_faults() & (HD_FAULT_CALIB_MISSING | HD_FAULT_CALIB_CORRUPT));

    /* change RAM, then reload from NVM */
    set_param(HD_PARAM_CALIB_GAIN_NM_PER_V, 9.0f);
    hd_can_cmd_t l = {0};
    l.opcode = HD_CMD_CALIB_LOAD;
    a = send_cmd(&l);
    TEST_ASSERT_EQUAL_UINT8(HD_CAN_RES_OK, a.result);
    TEST_ASSERT_EQUAL_FLOAT(6.5f, a.value);
    TEST_ASSERT_EQUAL_FLOAT(6.5f, fw.calib.gain_nm_per_v);

    /* NVM failure: error ACK, RAM calibration kept */
    mock.nvm_fail = true;
    a = send_cmd(&c);
    TEST_ASSERT_EQUAL_UINT8(HD_CAN_RES_NVM_ERROR, a.result);
    a = send_cmd(&l);
    TEST_ASSERT_EQUAL_UINT8(HD_CAN_RES_NVM_ERROR, a.result);
    TEST_ASSERT_EQUAL_FLOAT(6.5f, fw.calib.gain_nm_per_v);
}

static void test_random_frames_never_corrupt_the_state(void)
{
    init_fw();
    srand(12345);
    for (int i = 0; i < 3000; i++) {
        hal_can_frame_t f = {0};
        f.id = 0x601;
        f.len = (uint8_t)(rand() % 10 == 0 ? rand() % 9 : 8);
        for (int b = 0; b < 8; b++) {
            f.data[b] = (uint8_t)rand();
        }
        /* bias towards real opcodes so the argument checks are exercised */
        const uint8_t ops[] = {0x01, 0x10, 0x11, 0x12, 0x13, 0x20, 0x21, 0x40};
        if (rand() % 2) {
            f.data[0] = ops[rand() % 8];
        }
        if (f.data[0] == HD_CMD_SET_PARAM && f.data[2] == HD_PARAM_NODE_ID) {
            continue; /* would move the node away from 0x601 */
        }
        hd_fw_config_t before = fw.cfg;
        uint32_t n0 = hal_mock_tx_count(&mock);
        hd_fw_handle_frame(&fw, &f);
        hd_fw_background(&fw); /* NVM commands answer from here */
        const hal_can_frame_t *ack = hal_mock_tx(&mock, n0);
        TEST_ASSERT_NOT_NULL(ack);
        if (ack->data[2] != HD_CAN_RES_OK) {
            TEST_ASSERT_EQUAL_MEMORY(&before, &fw.cfg, sizeof before);
        }
        TEST_ASSERT_EQUAL_INT(HD_FW_OK, hd_fw_config_check(&fw.cfg));
        if (hal_mock_tx_count(&mock) > HAL_MOCK_TX_CAP - 10) {
            hal_mock_tx_clear(&mock);
        }
        if (i % 100 == 0) {
            run(1, 1000, 1);
            const hd_fw_sample_t *smp = hd_fw_last_sample(&fw);
            TEST_ASSERT_TRUE(!smp->valid || isfinite(smp->torque_filtered_nm));
            hal_mock_tx_clear(&mock);
        }
    }
}

static void test_end_of_samples_stops_the_isr(void)
{
    init_fw();
    run(5, 0, 1);
    hd_fw_isr(&fw); /* queue empty: HAL_ERR_END */
    TEST_ASSERT_TRUE(fw.ended);
    TEST_ASSERT_EQUAL_UINT8(HD_STATE_STOPPED, last_id(0x701)->data[0]);
    uint32_t ticks = hd_fw_counters(&fw)->ticks;
    hd_fw_isr(&fw);
    TEST_ASSERT_EQUAL_UINT32(ticks, hd_fw_counters(&fw)->ticks);
}

static void test_deadline_miss_from_the_clock(void)
{
    init_fw();
    run(3, 0, 1);
    mock.now_us += 5000u; /* the tick came 6 ms after the previous one */
    run(1, 0, 1);
    TEST_ASSERT_EQUAL_UINT32(5, hd_fw_counters(&fw)->deadline_misses);
    TEST_ASSERT_TRUE((last_faults() & HD_FAULT_DEADLINE_MISS) != 0u);
    run(1, 0, 1);
    TEST_ASSERT_EQUAL_HEX16(0, last_faults());
}

static void test_config_errors_are_refused_at_init(void)
{
    hd_fw_config_t bad = cfg;
    bad.node_id = 0;
    TEST_ASSERT_EQUAL_INT(HD_FW_ERR_NODE, hd_fw_init(&fw, &hal, &bad));
    bad = cfg;
    bad.kf.r_nm2 = -1.0f;
    TEST_ASSERT_EQUAL_INT(HD_FW_ERR_KF, hd_fw_init(&fw, &hal, &bad));
    bad = cfg;
    bad.motor_cpr = 0;
    TEST_ASSERT_EQUAL_INT(HD_FW_ERR_CPR, hd_fw_init(&fw, &hal, &bad));
    hal_t empty = {0};
    TEST_ASSERT_EQUAL_INT(HD_FW_ERR_HAL, hd_fw_init(&fw, &empty, &cfg));
    TEST_ASSERT_EQUAL_INT(HD_FW_ERR_NULL, hd_fw_init(NULL, &hal, &cfg));
}

int main(void)
{
    UNITY_BEGIN();
    RUN_TEST(test_telemetry_scaled_values_and_sequence);
    RUN_TEST(test_rate_divider_and_heartbeat_period);
    RUN_TEST(test_invalid_samples_are_flagged_and_not_sent_as_torque);
    RUN_TEST(test_faults_survive_decimation);
    RUN_TEST(test_encoder_glitch_is_ignored_and_flagged);
    RUN_TEST(test_encoder_fault_uses_the_previous_motion);
    RUN_TEST(test_nyquist_frozen_block_is_flagged);
    RUN_TEST(test_can_tx_full_and_bus_off_are_flagged);
    RUN_TEST(test_missing_calibration_uses_defaults_and_flags);
    RUN_TEST(test_set_and_get_parameters);
    RUN_TEST(test_rejected_commands_change_nothing);
    RUN_TEST(test_filter_blocks_by_command);
    RUN_TEST(test_node_id_telemetry_rate_and_tare);
    RUN_TEST(test_tare_without_samples_is_refused);
    RUN_TEST(test_calibration_save_and_load_by_command);
    RUN_TEST(test_random_frames_never_corrupt_the_state);
    RUN_TEST(test_end_of_samples_stops_the_isr);
    RUN_TEST(test_deadline_miss_from_the_clock);
    RUN_TEST(test_config_errors_are_refused_at_init);
    return UNITY_END();
}
