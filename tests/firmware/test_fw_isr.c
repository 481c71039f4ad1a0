/* The tick on the mock HAL: injected samples -> telemetry frames whose
 * scaled values are computed here independently (double precision),
 * sequence counter, rate divider, TELEM_C, heartbeat, boot report, fault
 * flags, calibration record handling, end of samples, deadlines.  Commands:
 * test_fw_commands.c. */
#include <math.h>
#include <stdlib.h>

#include "fw_rig.h"
#include "hd_params.h"

#define ID_A id_of(HD_CAN_FRAME_TELEM_A, 1)
#define ID_B id_of(HD_CAN_FRAME_TELEM_B, 1)
#define ID_C id_of(HD_CAN_FRAME_TELEM_C, 1)
#define ID_HB id_of(HD_CAN_FRAME_HEARTBEAT, 1)
#define ID_BOOT id_of(HD_CAN_FRAME_BOOT, 1)

void setUp(void)
{
    rig_reset();
}
void tearDown(void) {}

/* Counts every transmitted frame by frame type, beyond the mock's storage. */
static unsigned id_counts[256];
static void count_hook(void *ctx, const hal_can_frame_t *f, uint64_t t_us)
{
    (void)ctx;
    (void)t_us;
    id_counts[(f->id >> 8) & 0xFFu]++;
}

static void test_telemetry_scaled_values_and_sequence(void)
{
    init_fw();
    const int32_t counts = 5000;
    run(10, counts, 7);
    /* independent expectation: 6.6 * (5000 * 10/32768 - 0.1) = 9.41103... Nm */
    double torque = GAIN * (counts * VPC - OFFSET_V);
    long lsb = lround(torque / 0.01);
    TEST_ASSERT_EQUAL_UINT(10, count_id(ID_A));
    TEST_ASSERT_EQUAL_UINT(10, count_id(ID_B));
    TEST_ASSERT_EQUAL_UINT(1, count_id(ID_HB)); /* heartbeat on tick 0 only */
    TEST_ASSERT_EQUAL_UINT(1, count_id(ID_BOOT)); /* boot report on tick 0 only */
    unsigned seq = 0;
    for (uint32_t i = 0; i < hal_mock_tx_count(&mock); i++) {
        const hal_can_frame_t *f = hal_mock_tx(&mock, i);
        if (f->id == ID_A) {
            TEST_ASSERT_EQUAL_UINT8(HAL_CAN_FLAG_EXT, f->flags); /* 29-bit */
            TEST_ASSERT_EQUAL_UINT8(8, f->len);
            TEST_ASSERT_EQUAL_INT(lsb, i16_at(f, 2)); /* raw */
            TEST_ASSERT_EQUAL_INT(lsb, i16_at(f, 0)); /* filter off: filtered = raw */
            TEST_ASSERT_EQUAL_UINT8(seq, f->data[6]);
            const hal_can_frame_t *b = hal_mock_tx(&mock, i + 1);
            TEST_ASSERT_EQUAL_HEX32(ID_B, b->id); /* B follows A with the same seq */
            TEST_ASSERT_EQUAL_UINT8(seq, b->data[7]);
            TEST_ASSERT_EQUAL_UINT32(0, b->data[3] | (b->data[4] << 8) | (b->data[5] << 16));
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
    cfg.angle_telemetry_every = 5; /* TELEM_C with every 5th pair */
    init_fw();
    memset(id_counts, 0, sizeof id_counts);
    mock.tx_store = false;
    mock.tx_hook = count_hook;
    run(2001, 0, 1);
    TEST_ASSERT_EQUAL_UINT(501, id_counts[HD_CAN_FRAME_TELEM_A]); /* ticks 0, 4, ..., 2000 */
    TEST_ASSERT_EQUAL_UINT(501, id_counts[HD_CAN_FRAME_TELEM_B]);
    TEST_ASSERT_EQUAL_UINT(101, id_counts[HD_CAN_FRAME_TELEM_C]); /* pairs 0, 5, ..., 500 */
    TEST_ASSERT_EQUAL_UINT(3, id_counts[HD_CAN_FRAME_HEARTBEAT]); /* ticks 0, 1000, 2000 */
    mock.tx_store = true;
    mock.tx_hook = NULL;
    run(3, 0, 1);
    run(1, 0, 1); /* tick 2004: sent and stored */
    const hal_can_frame_t *a = last_id(ID_A);
    TEST_ASSERT_EQUAL_UINT8(501 % 256, a->data[6]); /* sequence wraps modulo 256 */
    cfg.telemetry_rate_hz = 0; /* off */
    hal_mock_init(&mock);
    hal_mock_bind(&mock, &hal);
    store_calibration((float)GAIN, (float)OFFSET_V);
    init_fw();
    run(50, 0, 1);
    TEST_ASSERT_EQUAL_UINT(0, count_id(ID_A));
    TEST_ASSERT_EQUAL_UINT(0, count_id(ID_C));
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
    TEST_ASSERT_EQUAL_HEX32(HD_FAULT_ADC_SATURATED, last_faults());
    TEST_ASSERT_EQUAL_INT(INT16_MIN, i16_at(last_id(ID_A), 0));
    TEST_ASSERT_EQUAL_INT(INT16_MIN, i16_at(last_id(ID_A), 2));
    TEST_ASSERT_FALSE(hd_fw_last_sample(&fw)->valid);
    push_special(HAL_ERR_FAULT, false, 0);
    TEST_ASSERT_EQUAL_HEX32(HD_FAULT_OPEN_BRIDGE, last_faults());
    push_special(HAL_ERR_IO, false, 0);
    TEST_ASSERT_EQUAL_HEX32(HD_FAULT_ADC_ERROR, last_faults());
    /* 30000 counts = 9.155 V -> 59.8 Nm: above a 50 Nm limit (written into
     * the live settings directly, so no command ticks change the counts) */
    fw.settings[fw.live_settings].cfg.torque_limit_nm = 50.0f;
    push_special(HAL_OK, false, 30000);
    TEST_ASSERT_EQUAL_HEX32(HD_FAULT_TORQUE_RANGE, last_faults());
    run(1, 100, 3);
    TEST_ASSERT_EQUAL_HEX32(0, last_faults());
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
    TEST_ASSERT_EQUAL_UINT(1, count_id(ID_A));
    run(1, 100, 3);                /* tick 10: telemetry carries the saturation */
    TEST_ASSERT_EQUAL_HEX32(HD_FAULT_ADC_SATURATED, last_faults());
    run(10, 100, 3);
    TEST_ASSERT_EQUAL_HEX32(0, last_faults());
}

static void test_encoder_glitch_is_ignored_and_flagged(void)
{
    init_fw();
    run(10, 0, 20);
    /* one-sample spike of +100000 counts (impossible at 1000 rad/s: 652 max) */
    motor += 20;
    hal_mock_push(&mock, 0, motor + 100000u);
    hd_fw_isr(&fw);
    TEST_ASSERT_EQUAL_HEX32(HD_FAULT_ENC_GLITCH, hd_fw_last_sample(&fw)->faults);
    double step_rad = 20.0 * 2.0 * TEST_PI / CPR;
    TEST_ASSERT_FLOAT_WITHIN(1e-6, step_rad, hd_fw_last_sample(&fw)->d_motor_angle_rad);
    run(1, 0, 20); /* back to the true count: the reverse jump is a glitch too */
    TEST_ASSERT_EQUAL_HEX32(HD_FAULT_ENC_GLITCH, hd_fw_last_sample(&fw)->faults);
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
    TEST_ASSERT_EQUAL_HEX32(HD_FAULT_ENC_FAULT, hd_fw_last_sample(&fw)->faults);
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
    TEST_ASSERT_EQUAL_INT(HD_RECORD_MISSING, hd_fw_record_status(&fw, HD_RECORD_KIND_CALIB));
    TEST_ASSERT_EQUAL_HEX32(HD_FAULT_CALIB_MISSING, last_faults());
    /* defaults (nominal 6.60 Nm/V, offset 0) are used, visibly */
    TEST_ASSERT_FLOAT_WITHIN(1e-4, 6.60 * 1000 * VPC, hd_fw_last_sample(&fw)->torque_raw_nm);
    const hal_can_frame_t *hb = last_id(ID_HB);
    TEST_ASSERT_EQUAL_UINT8(2, hb->data[6] & 0x0Fu); /* calibration record MISSING */
    TEST_ASSERT_EQUAL_UINT8(2, hb->data[6] >> 4);    /* no saved configuration either */
    TEST_ASSERT_EQUAL_UINT8(HD_STATE_DEGRADED, hb->data[0]);

    /* corrupt: flip a byte inside both copies */
    hal_mock_init(&mock);
    hal_mock_bind(&mock, &hal);
    store_calibration(7.0f, 0.2f);
    /* damage the record's gain in the only copy (copy A: the first save) */
    size_t off = hd_le_get_u16(mock.nvm + 16 + 4);
    mock.nvm[off + 13] ^= 0x5Au;
    init_fw();
    run(2, 1000, 1);
    TEST_ASSERT_EQUAL_INT(HD_RECORD_CORRUPT, hd_fw_record_status(&fw, HD_RECORD_KIND_CALIB));
    TEST_ASSERT_TRUE((last_faults() & HD_FAULT_CALIB_CORRUPT) != 0u);
    TEST_ASSERT_FLOAT_WITHIN(1e-4, 6.60 * 1000 * VPC, hd_fw_last_sample(&fw)->torque_raw_nm);

    /* NVM I/O error */
    mock.nvm_fail = true;
    init_fw();
    run(1, 0, 1);
    TEST_ASSERT_TRUE((last_faults() & HD_FAULT_CALIB_CORRUPT) != 0u);
}

/* hd_fw.h restates the calibration rows' bounds as macros (the fault tests
 * use them as "the largest accepted gain"); the table decides. */
static void test_calib_bound_macros_are_the_tables(void)
{
    const hd_param_info_t *g = hd_param_by_id(HD_PARAM_CALIB_GAIN_NM_PER_V);
    const hd_param_info_t *o = hd_param_by_id(HD_PARAM_CALIB_OFFSET_V);
    TEST_ASSERT_NOT_NULL(g);
    TEST_ASSERT_NOT_NULL(o);
    TEST_ASSERT_EQUAL_FLOAT(g->hi, HD_FW_CALIB_GAIN_MAX_NM_PER_V);
    TEST_ASSERT_EQUAL_FLOAT(o->hi, HD_FW_CALIB_OFFSET_MAX_V);
    TEST_ASSERT_EQUAL_FLOAT(o->lo, -HD_FW_CALIB_OFFSET_MAX_V);
}

static void test_end_of_samples_stops_the_isr(void)
{
    init_fw();
    run(5, 1234, 1);
    const uint64_t t_us = hd_fw_last_sample(&fw)->t_us;
    hd_fw_isr(&fw); /* queue empty: HAL_ERR_END */
    TEST_ASSERT_TRUE(fw.tick.ended);
    /* the last sample is still the last one the source gave (the tick
     * fills it in place: the ending tick must not touch it) */
    TEST_ASSERT_EQUAL_INT32(1234, hd_fw_last_sample(&fw)->bridge_counts);
    TEST_ASSERT_TRUE(hd_fw_last_sample(&fw)->valid);
    TEST_ASSERT_EQUAL_UINT64(t_us, hd_fw_last_sample(&fw)->t_us);
    TEST_ASSERT_EQUAL_UINT8(HD_STATE_STOPPED, last_id(ID_HB)->data[0]);
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
    TEST_ASSERT_EQUAL_HEX32(0, last_faults());
}

static void test_config_errors_are_refused_at_init(void)
{
    hd_fw_config_t bad = cfg;
    bad.node_id = 0;
    unsigned which = 0;
    TEST_ASSERT_EQUAL_INT(HD_FW_ERR_RANGE, hd_fw_init(&fw, &hal, &bad));
    TEST_ASSERT_EQUAL_INT(HD_FW_ERR_RANGE, hd_fw_config_check(&bad, &which));
    TEST_ASSERT_EQUAL_UINT(HD_PARAM_NODE_ID, which);
    bad = cfg;
    bad.kf.r_nm2 = -1.0f;
    TEST_ASSERT_EQUAL_INT(HD_FW_ERR_RANGE, hd_fw_config_check(&bad, &which));
    TEST_ASSERT_EQUAL_UINT(HD_PARAM_R_NM2, which);
    bad = cfg;
    bad.motor_cpr = 0;
    TEST_ASSERT_EQUAL_INT(HD_FW_ERR_RANGE, hd_fw_config_check(&bad, &which));
    TEST_ASSERT_EQUAL_UINT(HD_PARAM_MOTOR_CPR, which);
    bad = cfg;
    bad.kf.blocks[0].order = -2.0f; /* in no table row: the filter's own check */
    TEST_ASSERT_EQUAL_INT(HD_FW_ERR_KF, hd_fw_init(&fw, &hal, &bad));
    hal_t empty = {0};
    TEST_ASSERT_EQUAL_INT(HD_FW_ERR_HAL, hd_fw_init(&fw, &empty, &cfg));
    TEST_ASSERT_EQUAL_INT(HD_FW_ERR_NULL, hd_fw_init(NULL, &hal, &cfg));
}


static void test_angle_telemetry_carries_the_raw_counts(void)
{
    cfg.angle_telemetry_every = 1;
    init_fw();
    motor = 0xFFFFFFC0u; /* the free-running counter, about to wrap */
    run(100, 0, 1);      /* 4 frames a tick: within the mock's transmit log */
    const hal_can_frame_t *c = last_id(ID_C);
    TEST_ASSERT_NOT_NULL(c);
    hd_can_angle_t ang;
    TEST_ASSERT_EQUAL_INT(0, hd_can_decode_angle(c, &ang));
    TEST_ASSERT_EQUAL_HEX32(motor, ang.motor_counts);
    TEST_ASSERT_FALSE(ang.has_output); /* the mock has no output encoder */
    TEST_ASSERT_EQUAL_UINT8(last_id(ID_A)->data[6], ang.seq); /* same tick as the pair */
}

static void test_boot_report_says_why_and_what(void)
{
    init_fw();
    run(1, 0, 1);
    hd_can_boot_t b;
    TEST_ASSERT_EQUAL_INT(0, hd_can_decode_boot(last_id(ID_BOOT), &b));
    TEST_ASSERT_EQUAL_UINT8(HD_CAN_PROTOCOL_VERSION, b.protocol_version);
    TEST_ASSERT_FALSE(b.config_from_record);
    TEST_ASSERT_EQUAL_UINT8(HD_RECORD_MISSING, b.config_status);
    TEST_ASSERT_FALSE(b.fault_valid);
}

static void test_frames_for_others_are_counted_not_queued(void)
{
    init_fw();
    hal_can_frame_t f = {0};
    f.len = 8;
    f.id = 0x601; /* 11-bit: not ours */
    hal_mock_push_rx(&mock, &f);
    f.id = id_of(HD_CAN_FRAME_CMD, 2); /* another node */
    f.flags = HAL_CAN_FLAG_EXT;
    hal_mock_push_rx(&mock, &f);
    f.id = id_of(HD_CAN_FRAME_TELEM_A, 1); /* our own telemetry type, echoed */
    hal_mock_push_rx(&mock, &f);
    run(2, 0, 1);
    TEST_ASSERT_EQUAL_UINT32(3, hd_fw_counters(&fw)->foreign_frames);
    TEST_ASSERT_EQUAL_UINT32(0, hd_fw_counters(&fw)->commands);
}

/* The tick writes every field of the sample (the gauge does not clear it
 * first): two runs on the same inputs, with the sample filled with 0x00 in
 * one and 0xFF in the other before each tick, give the same fields, over
 * good ticks, ADC errors, saturation, encoder faults and an output encoder
 * coming and going. */
_Static_assert(sizeof(hd_fw_sample_t) == 80u,
               "a new hd_fw_sample_t field: add it to poisoned_run's comparison");
enum { POISON_TICKS = 60 };

static void poisoned_run(uint8_t poison, hd_fw_sample_t out[POISON_TICKS])
{
    rig_reset();
    init_fw();
    for (unsigned i = 0; i < POISON_TICKS; i++) {
        hal_mock_sample_t smp;
        memset(&smp, 0, sizeof smp);
        smp.adc.bridge_counts = 1000 + 37 * (int32_t)i;
        smp.adc_rc = (i % 7u == 3u) ? HAL_ERR_IO : HAL_OK;
        smp.adc.saturated = i % 11u == 5u;
        smp.enc.motor_counts = 5u * i;
        smp.enc.output_counts = i / 2u;
        smp.enc.has_output = i >= 20u && i < 40u;
        smp.enc.fault = i % 13u == 6u;
        TEST_ASSERT_EQUAL_INT(HAL_OK, hal_mock_push_sample(&mock, &smp));
        memset(&fw.last, poison, sizeof fw.last);
        hd_fw_isr(&fw);
        hd_fw_background(&fw);
        out[i] = fw.last;
    }
}

#define SAME_FIELD(f)                                                                  \
    TEST_ASSERT_EQUAL_INT_MESSAGE(0, memcmp(&a[i].f, &b[i].f, sizeof a[i].f), #f)

static void test_every_tick_writes_every_sample_field(void)
{
    static hd_fw_sample_t a[POISON_TICKS], b[POISON_TICKS];
    poisoned_run(0x00u, a);
    poisoned_run(0xFFu, b);
    for (unsigned i = 0; i < POISON_TICKS; i++) {
        SAME_FIELD(t_us);
        SAME_FIELD(bridge_counts);
        SAME_FIELD(bridge_v);
        SAME_FIELD(torque_raw_nm);
        SAME_FIELD(torque_filtered_nm);
        SAME_FIELD(ripple_nm);
        SAME_FIELD(torque_expected_nm);
        SAME_FIELD(torque_expected_var_nm2);
        SAME_FIELD(feedforward_nm);
        SAME_FIELD(motor_current_a);
        SAME_FIELD(motor_velocity_rad_s);
        SAME_FIELD(d_motor_angle_rad);
        SAME_FIELD(d_output_angle_rad);
        SAME_FIELD(motor_counts);
        SAME_FIELD(output_counts);
        SAME_FIELD(has_output);
        SAME_FIELD(valid);
        SAME_FIELD(faults);
        SAME_FIELD(kf_status);
    }
    TEST_ASSERT_FALSE(a[3].valid);      /* the paths ran: an ADC error, */
    TEST_ASSERT_TRUE(a[25].has_output); /* an output encoder */
    TEST_ASSERT_TRUE(a[12].valid);      /* and good samples */
}

/* The mock's receive copies the header and the bytes a frame carries (the
 * classic 8, or an FD frame's len), not the whole buffer: each frame comes
 * back with the bytes it was pushed with. */
static void test_mock_receive_gives_the_frames_as_pushed(void)
{
    static const uint8_t lens[] = {0, 3, 8, 12, 64};
    for (unsigned k = 0; k < sizeof lens; k++) {
        hal_can_frame_t in = {0};
        in.id = 0x1234567u + k;
        in.len = lens[k];
        in.flags = (uint8_t)(HAL_CAN_FLAG_EXT | (lens[k] > 8u ? HAL_CAN_FLAG_FD : 0u));
        for (unsigned i = 0; i < HAL_CAN_MAX_DATA; i++) {
            in.data[i] = (uint8_t)(7u * i + k + 1u);
        }
        TEST_ASSERT_EQUAL_INT(HAL_OK, hal_mock_push_rx(&mock, &in));
        hal_can_frame_t out;
        memset(&out, 0xA5, sizeof out);
        TEST_ASSERT_EQUAL_INT(HAL_OK, hal.can.recv(hal.can.ctx, &out));
        TEST_ASSERT_EQUAL_HEX32(in.id, out.id);
        TEST_ASSERT_EQUAL_UINT8(in.len, out.len);
        TEST_ASSERT_EQUAL_HEX8(in.flags, out.flags);
        TEST_ASSERT_EQUAL_INT(0, memcmp(in.data, out.data, in.len));
    }
    hal_can_frame_t none;
    TEST_ASSERT_EQUAL_INT(HAL_ERR_NO_DATA, hal.can.recv(hal.can.ctx, &none));
}

int main(int argc, char **argv)
{
    if (UnityParseOptions(argc, argv) != 0) {
        return 1;
    }
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
    RUN_TEST(test_calib_bound_macros_are_the_tables);
    RUN_TEST(test_end_of_samples_stops_the_isr);
    RUN_TEST(test_deadline_miss_from_the_clock);
    RUN_TEST(test_config_errors_are_refused_at_init);
    RUN_TEST(test_angle_telemetry_carries_the_raw_counts);
    RUN_TEST(test_boot_report_says_why_and_what);
    RUN_TEST(test_frames_for_others_are_counted_not_queued);
    RUN_TEST(test_mock_receive_gives_the_frames_as_pushed);
    RUN_TEST(test_every_tick_writes_every_sample_field);
    return UNITY_END();
}
