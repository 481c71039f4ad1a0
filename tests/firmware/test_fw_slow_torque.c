/* Slow torque in the firmware (issue 12, docs/design/slow-torque.md), on the mock
 * HAL: the feed-forward frame (latched, stale, ramp, every rejection), the
 * motor-current channel, and the profile record (boot import at the
 * absolute angle of the first sample, every refusal, upload, load, save,
 * clear, restarts, learning mode).
 *
 * Expectations are closed forms from the documented rules: T_exp = the
 * feed-forward (J = b = Fc = 0) or k_i i; a profile line predicts
 * a cos(k alpha) + b sin(k alpha) at alpha = 2 pi (counts mod cpr) / cpr,
 * computed here in double; profile payloads are built byte by byte from the
 * layout in hd_fw_records.h, not with the firmware's encoder. */
#include <math.h>
#include <stdio.h>

#include "fw_rig.h"
#include "hd_fw_records.h"
#include "hd_params.h"

#define LIMIT_NM 200.0f

static uint32_t outc; /* output encoder counts of the next sample */
static bool with_output;

void setUp(void)
{
    rig_reset();
    outc = 0u;
    with_output = false;
}
void tearDown(void) {}

/* n ticks: the motor moves `step` counts, the output encoder (same cpr)
 * counts the motor's travel / 100 (the gear ratio). */
static void tick_n(unsigned n, int32_t counts, uint32_t step)
{
    for (unsigned i = 0; i < n; i++) {
        motor += step;
        outc = motor / 100u;
        hal_mock_sample_t s;
        memset(&s, 0, sizeof s);
        s.adc.bridge_counts = counts;
        s.enc.motor_counts = motor;
        s.enc.output_counts = outc;
        s.enc.has_output = with_output;
        TEST_ASSERT_EQUAL_INT(0, hal_mock_push_sample(&mock, &s));
        hd_fw_isr(&fw);
        hd_fw_background(&fw);
    }
}

static const hd_fw_sample_t *last(void)
{
    return hd_fw_last_sample(&fw);
}

/* ------------------------------------------------------------ feed-forward */

static hal_can_frame_t ff_frame(float v, uint8_t seq)
{
    hal_can_frame_t f;
    memset(&f, 0, sizeof f);
    f.id = hd_can_id(HD_CAN_FRAME_FEEDFORWARD, 1);
    f.flags = HAL_CAN_FLAG_EXT;
    f.len = 8;
    memcpy(f.data, &v, 4); /* little-endian host */
    f.data[4] = seq;
    return f;
}

static void send_ff(float v, uint8_t seq)
{
    hal_can_frame_t f = ff_frame(v, seq);
    TEST_ASSERT_EQUAL_INT(0, hal_mock_push_rx(&mock, &f));
}

static void test_feedforward_is_latched_into_t_exp_and_goes_stale_with_a_ramp(void)
{
    cfg.feedforward_timeout_ms = 5u;
    cfg.feedforward_ramp_ms = 10u;
    init_fw();
    send_ff(2.5f, 1);
    tick_n(1, 1000, 3);
    TEST_ASSERT_EQUAL_FLOAT(2.5f, last()->torque_expected_nm); /* J = b = Fc = 0 */
    TEST_ASSERT_EQUAL_FLOAT(2.5f, live_pipe()->torque_expected_nm);
    TEST_ASSERT_EQUAL_UINT32(1, hd_fw_counters(&fw)->feedforward_frames);
    TEST_ASSERT_EQUAL_HEX32(0, last()->faults & (HD_FAULT_FF_STALE | HD_FAULT_FF_REJECTED));
    /* fresh for 5 ms after its tick */
    for (unsigned i = 1; i <= 5; i++) {
        tick_n(1, 1000, 3);
        TEST_ASSERT_EQUAL_FLOAT(2.5f, last()->feedforward_nm);
        TEST_ASSERT_EQUAL_HEX32(0, last()->faults & HD_FAULT_FF_STALE);
    }
    /* then stale: flagged, ramps to zero over 10 ms, stays there */
    for (unsigned j = 1; j <= 12; j++) {
        tick_n(1, 1000, 3);
        TEST_ASSERT_TRUE((last()->faults & HD_FAULT_FF_STALE) != 0u);
        double expect = j >= 10 ? 0.0 : 2.5 * (1.0 - j / 10.0);
        TEST_ASSERT_DOUBLE_WITHIN(1e-6, expect, (double)last()->feedforward_nm);
        TEST_ASSERT_DOUBLE_WITHIN(1e-6, expect, (double)last()->torque_expected_nm);
    }
    /* the same sequence number again is not new data */
    send_ff(7.0f, 1);
    tick_n(1, 1000, 3);
    TEST_ASSERT_TRUE((last()->faults & HD_FAULT_FF_STALE) != 0u);
    TEST_ASSERT_EQUAL_FLOAT(0.0f, last()->feedforward_nm);
    /* a new one is used at once */
    send_ff(-4.0f, 2);
    tick_n(1, 1000, 3);
    TEST_ASSERT_EQUAL_HEX32(0, last()->faults & HD_FAULT_FF_STALE);
    TEST_ASSERT_EQUAL_FLOAT(-4.0f, last()->torque_expected_nm);
    TEST_ASSERT_EQUAL_UINT32(2, hd_fw_counters(&fw)->feedforward_frames);
}

static void test_a_stale_ramp_of_zero_drops_at_once_and_none_received_is_stale(void)
{
    cfg.feedforward_timeout_ms = 3u;
    cfg.feedforward_ramp_ms = 0u;
    init_fw();
    tick_n(2, 1000, 3);
    TEST_ASSERT_TRUE((last()->faults & HD_FAULT_FF_STALE) != 0u); /* expected, never came */
    TEST_ASSERT_EQUAL_FLOAT(0.0f, last()->torque_expected_nm);
    send_ff(3.0f, 9);
    tick_n(4, 1000, 3);
    TEST_ASSERT_EQUAL_FLOAT(3.0f, last()->torque_expected_nm);
    tick_n(1, 1000, 3);
    TEST_ASSERT_EQUAL_FLOAT(0.0f, last()->torque_expected_nm);
}

/* Every bad frame: flagged on its tick, ignored, the last good value kept. */
static void test_bad_feedforward_frames_are_flagged_and_never_fed(void)
{
    cfg.feedforward_timeout_ms = 1000u;
    init_fw();
    send_ff(1.5f, 1);
    tick_n(1, 1000, 3);
    TEST_ASSERT_EQUAL_FLOAT(1.5f, last()->torque_expected_nm);
    const float bad_values[] = {NAN, INFINITY, -INFINITY, LIMIT_NM * 1.001f, -LIMIT_NM * 1.5f,
                                3.0e38f};
    uint8_t seq = 2;
    for (unsigned i = 0; i < sizeof bad_values / sizeof bad_values[0]; i++) {
        send_ff(bad_values[i], seq++);
        tick_n(1, 1000, 3);
        TEST_ASSERT_TRUE_MESSAGE((last()->faults & HD_FAULT_FF_REJECTED) != 0u, "value");
        TEST_ASSERT_EQUAL_FLOAT(1.5f, last()->torque_expected_nm);
        tick_n(1, 1000, 3);
        TEST_ASSERT_EQUAL_HEX32(0, last()->faults & HD_FAULT_FF_REJECTED); /* one tick only */
    }
    hal_can_frame_t f = ff_frame(5.0f, seq++);
    f.len = 4;
    TEST_ASSERT_EQUAL_INT(0, hal_mock_push_rx(&mock, &f));
    f = ff_frame(5.0f, seq++);
    f.flags |= HAL_CAN_FLAG_RTR;
    TEST_ASSERT_EQUAL_INT(0, hal_mock_push_rx(&mock, &f));
    f = ff_frame(5.0f, seq++);
    f.flags |= HAL_CAN_FLAG_FD;
    TEST_ASSERT_EQUAL_INT(0, hal_mock_push_rx(&mock, &f));
    tick_n(1, 1000, 3);
    TEST_ASSERT_TRUE((last()->faults & HD_FAULT_FF_REJECTED) != 0u);
    TEST_ASSERT_EQUAL_FLOAT(1.5f, last()->torque_expected_nm);
    TEST_ASSERT_EQUAL_UINT32(1, hd_fw_counters(&fw)->feedforward_frames);
    TEST_ASSERT_EQUAL_UINT32(7, hd_fw_counters(&fw)->by_fault[HD_FAULT_BIT_FF_REJECTED]);
    /* a frame for another node is not ours */
    uint32_t foreign = hd_fw_counters(&fw)->foreign_frames;
    f = ff_frame(9.0f, seq++);
    f.id = hd_can_id(HD_CAN_FRAME_FEEDFORWARD, 2);
    TEST_ASSERT_EQUAL_INT(0, hal_mock_push_rx(&mock, &f));
    tick_n(1, 1000, 3);
    TEST_ASSERT_EQUAL_FLOAT(1.5f, last()->torque_expected_nm);
    TEST_ASSERT_EQUAL_UINT32(foreign + 1u, hd_fw_counters(&fw)->foreign_frames);
}

static void test_no_feedforward_expected_ignores_frames(void)
{
    init_fw(); /* feedforward_timeout_ms = 0 by default */
    TEST_ASSERT_EQUAL_UINT16(0, live_cfg()->feedforward_timeout_ms);
    send_ff(2.0f, 1);
    send_ff(NAN, 2);
    tick_n(3, 1000, 3);
    TEST_ASSERT_EQUAL_FLOAT(0.0f, last()->torque_expected_nm);
    TEST_ASSERT_EQUAL_HEX32(0, last()->faults & (HD_FAULT_FF_STALE | HD_FAULT_FF_REJECTED));
    /* switched on over CAN: the next frame is used */
    TEST_ASSERT_EQUAL_UINT8(HD_CAN_RES_OK, set_param(HD_PARAM_FEEDFORWARD_TIMEOUT_MS, 50.0f).result);
    send_ff(2.0f, 3);
    tick_n(1, 1000, 3);
    TEST_ASSERT_EQUAL_FLOAT(2.0f, last()->torque_expected_nm);
}

/* ----------------------------------------------------------- motor current */

/* One tick with this current reading; the motor turns by `counts`. */
static void push_sample_current(float amps, int rc, bool fault, uint32_t counts)
{
    motor += counts;
    hal_mock_sample_t s;
    memset(&s, 0, sizeof s);
    s.adc.bridge_counts = 1000;
    s.enc.motor_counts = motor;
    s.cur.motor_current_a = amps;
    s.cur.fault = fault;
    s.cur_rc = rc;
    TEST_ASSERT_EQUAL_INT(0, hal_mock_push_sample(&mock, &s));
    hd_fw_isr(&fw);
    hd_fw_background(&fw);
}

static void push_current(float amps, int rc, bool fault)
{
    push_sample_current(amps, rc, fault, 3u);
}

static void push_current_still(float amps)
{
    push_sample_current(amps, HAL_OK, false, 0u);
}

/* The firmware booted with a current channel and this current term. */
static void init_fw_with_current(hd_expected_current_config_t term, float filter_hz)
{
    mock.current_channel = true;
    hal_mock_bind(&mock, &hal);
    cfg.current = term;
    cfg.current_filter_hz = filter_hz;
    init_fw();
}

static void test_motor_current_enters_t_exp_and_a_bad_reading_holds(void)
{
    mock.current_channel = true;
    hal_mock_bind(&mock, &hal);
    cfg.current.nm_per_a = 50.0f;
    cfg.current_filter_hz = 0.0f; /* unfiltered: exact values (the low-pass: below) */
    init_fw();
    push_current(0.2f, HAL_OK, false);
    TEST_ASSERT_DOUBLE_WITHIN(1e-5, 10.0, (double)last()->torque_expected_nm);
    TEST_ASSERT_EQUAL_FLOAT(0.2f, last()->motor_current_a);
    push_current(-0.1f, HAL_OK, false);
    TEST_ASSERT_DOUBLE_WITHIN(1e-5, -5.0, (double)last()->torque_expected_nm);
    /* failed read, fault flag, NaN: CURRENT_ERROR and the last good value */
    push_current(3.0f, HAL_ERR_IO, false);
    TEST_ASSERT_TRUE((last()->faults & HD_FAULT_CURRENT_ERROR) != 0u);
    TEST_ASSERT_DOUBLE_WITHIN(1e-5, -5.0, (double)last()->torque_expected_nm);
    push_current(3.0f, HAL_OK, true);
    TEST_ASSERT_TRUE((last()->faults & HD_FAULT_CURRENT_ERROR) != 0u);
    TEST_ASSERT_DOUBLE_WITHIN(1e-5, -5.0, (double)last()->torque_expected_nm);
    push_current(NAN, HAL_OK, false);
    TEST_ASSERT_TRUE((last()->faults & HD_FAULT_CURRENT_ERROR) != 0u);
    TEST_ASSERT_DOUBLE_WITHIN(1e-5, -5.0, (double)last()->torque_expected_nm);
    push_current(0.3f, HAL_OK, false);
    TEST_ASSERT_EQUAL_HEX32(0, last()->faults & HD_FAULT_CURRENT_ERROR);
    TEST_ASSERT_DOUBLE_WITHIN(1e-5, 15.0, (double)last()->torque_expected_nm);
    /* unused (k_i = 0, live): no term, and a bad reading is no fault */
    TEST_ASSERT_EQUAL_UINT8(HD_CAN_RES_OK, set_param(HD_PARAM_CURRENT_NM_PER_A, 0.0f).result);
    push_current(1.0f, HAL_ERR_IO, false);
    TEST_ASSERT_EQUAL_HEX32(0, last()->faults & HD_FAULT_CURRENT_ERROR);
    TEST_ASSERT_EQUAL_FLOAT(0.0f, last()->torque_expected_nm);
}

/* The current term's low-pass: two first-order stages, backward Euler,
 * y_n = y_{n-1} + a (u_n - y_{n-1}), a = w / (1 + w), w = 2 pi f ts, on the
 * current; the velocity (from the motor increments / N) likewise, the
 * acceleration is the filtered velocity's difference / ts.  The two stages
 * lag a ramp by L = 2 (1 - a) / a ticks: T_exp is the model on the filtered
 * inputs plus L times its change over the tick (the lag extrapolated away),
 * and the filter is given that correction's square as variance (no Coulomb
 * term, no error_nm here).  Computed here in double from that description. */
static void test_motor_current_low_pass(void)
{
    init_fw_with_current((hd_expected_current_config_t){.nm_per_a = 10.0f,
                                                        .viscous_nm_s_rad = 2.0f,
                                                        .inertia_kgm2 = 0.5f},
                         10.0f);
    push_current(0.0f, HAL_OK, false); /* primes at 0 A and 0 rad/s; then 3 counts/tick */
    const double w = 2.0 * TEST_PI * 10.0 * 0.001, a = w / (1.0 + w);
    const double v0 = 3.0 * 2.0 * TEST_PI / 4096.0 / 100.0 / 0.001; /* output rad/s */
    double i1 = 0.0, i2 = 0.0, w1 = 0.0, w2 = 0.0; /* the first reading has no increment */
    const double lag_ticks = 2.0 * (1.0 - a) / a;
    TEST_ASSERT_EQUAL_FLOAT(0.0f, last()->torque_expected_var_nm2); /* priming tick */
    double prev = 0.0; /* the model at the priming tick */
    for (unsigned n = 1; n <= 200; n++) {
        push_current(1.0f, HAL_OK, false);
        i1 += a * (1.0 - i1);
        i2 += a * (i1 - i2);
        w1 += a * (v0 - w1);
        double dw = a * (w1 - w2);
        w2 += dw;
        const double model = 10.0 * i2 - 0.5 * dw / 0.001 - 2.0 * w2;
        const double lead = lag_ticks * (model - prev);
        TEST_ASSERT_DOUBLE_WITHIN(5e-3, model + lead, (double)last()->torque_expected_nm);
        TEST_ASSERT_DOUBLE_WITHIN(5e-3 * lead * lead + 1e-6, lead * lead,
                                  (double)last()->torque_expected_var_nm2);
        prev = model;
    }
    TEST_ASSERT_DOUBLE_WITHIN(0.02, 10.0 - 2.0 * v0, (double)last()->torque_expected_nm);
}

/* A ramp of current (a load growing at a constant rate, no motion): after
 * the stages settle, T_exp is k_i times the current of this very tick, where
 * the low-pass alone lags it by L ticks' growth. */
static void test_motor_current_lag_is_extrapolated_away(void)
{
    init_fw_with_current((hd_expected_current_config_t){.nm_per_a = 10.0f}, 10.0f);
    const double w = 2.0 * TEST_PI * 10.0 * 0.001, a = w / (1.0 + w);
    const double lag_ticks = 2.0 * (1.0 - a) / a, slope_a = 1e-3; /* per tick */
    for (unsigned n = 0; n <= 600; n++) {
        const double amps = slope_a * (double)n;
        push_current_still((float)amps);
        if (n > 400) {
            TEST_ASSERT_DOUBLE_WITHIN(2e-3, 10.0 * amps, (double)last()->torque_expected_nm);
            /* (the filtered current alone is lag_ticks x slope behind) */
            TEST_ASSERT_DOUBLE_WITHIN(2e-3, pow(10.0 * slope_a * lag_ticks, 2.0),
                                      (double)last()->torque_expected_var_nm2);
        }
    }
}

/* The variance's other two terms: near a stop the Coulomb friction's sign is
 * not known, at a standstill its value is anywhere in +-Fc_r (the smoothed
 * sign spread over +-v_eps: Fc_r / 2), and current_error_nm is added as its
 * square; at a steady speed far above v_eps only error_nm is left. */
static void test_motor_current_variance_at_standstill_and_speed(void)
{
    init_fw_with_current(
        (hd_expected_current_config_t){.nm_per_a = 10.0f, .coulomb_nm = 0.8f, .error_nm = 0.05f},
        10.0f);
    for (unsigned n = 0; n < 300; n++) {
        push_current_still(0.5f);
    }
    TEST_ASSERT_DOUBLE_WITHIN(1e-5, 0.4 * 0.4 + 0.05 * 0.05,
                              (double)last()->torque_expected_var_nm2);
    for (unsigned n = 0; n < 600; n++) {
        push_sample_current(0.5f, HAL_OK, false, 60u);
    }
    /* 60 counts per tick: v = 0.92 rad/s at the output, 92 v_eps */
    const double v = 60.0 * 2.0 * TEST_PI / 4096.0 / 100.0 / 0.001, eps = 0.01;
    const double spread = 0.4 * ((v + eps) / (v + 2.0 * eps) - (v - eps) / v);
    TEST_ASSERT_DOUBLE_WITHIN(1e-6, 0.05 * 0.05 + spread * spread,
                              (double)last()->torque_expected_var_nm2);
}

static void test_no_current_channel(void)
{
    cfg.current.nm_per_a = 50.0f;
    init_fw();
    TEST_ASSERT_NULL(hal.sensors.current_read);
    tick_n(2, 1000, 3);
    TEST_ASSERT_FLOAT_IS_NAN(last()->motor_current_a);
    TEST_ASSERT_EQUAL_FLOAT(0.0f, last()->torque_expected_nm);
    TEST_ASSERT_EQUAL_HEX32(0, last()->faults & HD_FAULT_CURRENT_ERROR);
}

/* ---------------------------------------------------------------- profiles */

typedef struct {
    uint8_t lock, order;
    float a, b;
} line_t;

/* The payload of hd_fw_records.h, byte by byte. */
/* The profile record's payload, written from hd_fw_records.h's layout:
 * version 2 with its load_nm, or version 1 (no load_nm) when load_nm is
 * NAN. */
static size_t payload_load(uint8_t *p, float gear, uint32_t mcpr, uint32_t ocpr, const line_t *l,
                           unsigned n, float load_nm)
{
    const size_t head = isnan(load_nm) ? 13u : 17u;
    memcpy(p, &gear, 4);
    for (int i = 0; i < 4; i++) {
        p[4 + i] = (uint8_t)(mcpr >> (8 * i));
        p[8 + i] = (uint8_t)(ocpr >> (8 * i));
    }
    if (head == 17u) {
        memcpy(p + 12, &load_nm, 4);
    }
    p[head - 1u] = (uint8_t)n;
    for (unsigned i = 0; i < n; i++) {
        uint8_t *q = p + head + 10 * i;
        q[0] = l[i].lock;
        q[1] = l[i].order;
        memcpy(q + 2, &l[i].a, 4);
        memcpy(q + 6, &l[i].b, 4);
    }
    return head + 10u * n;
}

static size_t payload(uint8_t *p, float gear, uint32_t mcpr, uint32_t ocpr, const line_t *l,
                      unsigned n)
{
    return payload_load(p, gear, mcpr, ocpr, l, n, 0.0f);
}

static void store_payload(const uint8_t *p, size_t len, uint16_t version)
{
    hd_store_io_t s = storage();
    TEST_ASSERT_EQUAL_INT(HD_RECORD_OK, hd_store_save(&s, HD_RECORD_KIND_PROFILE, version, p, len));
}

static void store_profile(float gear, uint32_t mcpr, uint32_t ocpr, const line_t *l, unsigned n)
{
    uint8_t p[128];
    store_payload(p, payload(p, gear, mcpr, ocpr, l, n), HD_PROFILE_RECORD_VERSION);
}

/* The ripple a profile predicts at the absolute angles of these counts. */
static double predicted(const line_t *l, unsigned n, uint32_t mcounts, uint32_t ocounts,
                        bool output)
{
    double r = 0.0;
    for (unsigned i = 0; i < n; i++) {
        if (l[i].lock == HD_KF_LOCK_OUTPUT && !output) {
            continue;
        }
        uint32_t c = l[i].lock == HD_KF_LOCK_MOTOR ? mcounts : ocounts;
        double alpha = 2.0 * TEST_PI * (double)(c % CPR) / (double)CPR;
        r += (double)l[i].a * cos(l[i].order * alpha) + (double)l[i].b * sin(l[i].order * alpha);
    }
    return r;
}

static const line_t LINES[] = {
    {HD_KF_LOCK_MOTOR, 2, 0.7f, -0.4f},
    {HD_KF_LOCK_MOTOR, 4, 0.1f, 0.25f},
    {HD_KF_LOCK_OUTPUT, 1, 0.3f, 0.2f},
};

static uint8_t heartbeat_profile_status(void)
{
    const hal_can_frame_t *hb = last_id(id_of(HD_CAN_FRAME_HEARTBEAT, 1));
    TEST_ASSERT_NOT_NULL(hb);
    return hb->data[7];
}

static void boot_filtering(void)
{
    cfg.filter_enabled = 1;
    cfg.telemetry_rate_hz = 0; /* heartbeats and ACKs only: the transmit log keeps them all */
    cfg.output_cpr = CPR;
    init_fw();
}

static void test_boot_predicts_the_stored_profile_from_the_first_sample(void)
{
    with_output = true;
    motor = 1234567u - 5u; /* any absolute start: the first sample is at 1234567 */
    store_profile(100.0f, CPR, CPR, LINES, 3);
    boot_filtering();
    TEST_ASSERT_EQUAL_INT(HD_RECORD_OK, hd_fw_record_status(&fw, HD_RECORD_KIND_PROFILE));
    tick_n(1, 1000, 5);
    TEST_ASSERT_EQUAL_UINT32(1234567u, last()->motor_counts);
    double expect = predicted(LINES, 3, 1234567u, 12345u, true);
    TEST_ASSERT_DOUBLE_WITHIN(2e-5, expect, (double)last()->ripple_nm);
    TEST_ASSERT_TRUE(fabs(expect) > 0.3); /* not a zero crossing by chance */
    TEST_ASSERT_EQUAL_UINT32(1, hd_fw_counters(&fw)->profile_imports);
    TEST_ASSERT_EQUAL_HEX32(0, last()->faults & HD_FAULT_PROFILE_UNUSABLE);
}

/* The record's load_nm reaches the filter as the held output rows' T_c; a
 * version-1 record (saved before the profile kept its load) still boots,
 * its lines the same, its load unknown (-1). */
static void boot_payload(float load_nm)
{
    uint8_t p[128];
    with_output = true;
    const size_t len = payload_load(p, 100.0f, CPR, CPR, LINES, 3, load_nm);
    store_payload(p, len, isnan(load_nm) ? HD_PROFILE_RECORD_VERSION_V1
                                         : HD_PROFILE_RECORD_VERSION);
    boot_filtering();
    TEST_ASSERT_EQUAL_INT(HD_RECORD_OK, hd_fw_record_status(&fw, HD_RECORD_KIND_PROFILE));
    tick_n(1, 1000, 5);
    TEST_ASSERT_EQUAL_UINT32(1, hd_fw_counters(&fw)->profile_imports);
    TEST_ASSERT_DOUBLE_WITHIN(2e-5, predicted(LINES, 3, motor, outc, true),
                              (double)last()->ripple_nm);
}

static void test_profile_load_reaches_the_filter_and_version_1_still_boots(void)
{
    boot_payload(2.5f);
    TEST_ASSERT_EQUAL_FLOAT(2.5f, live_pipe()->kf.follow_load_nm);
    boot_payload(NAN);
    TEST_ASSERT_EQUAL_FLOAT(-1.0f, live_pipe()->kf.follow_load_nm);
}

static void test_without_an_output_encoder_output_lines_are_not_used(void)
{
    store_profile(100.0f, CPR, CPR, LINES, 3);
    boot_filtering();
    tick_n(1, 1000, 5);
    double expect = predicted(LINES, 3, motor, 0u, false);
    TEST_ASSERT_DOUBLE_WITHIN(2e-5, expect, (double)last()->ripple_nm);
    TEST_ASSERT_TRUE(fabs(predicted(LINES, 3, motor, 0u, true) - expect) > 0.1);
}

/* Each unusable record: its status, the fault on every tick, the filter
 * from zero (no ripple on the first sample). */
static void check_refused(int status)
{
    with_output = true;
    boot_filtering();
    tick_n(1, 1000, 5);
    TEST_ASSERT_EQUAL_INT(status, hd_fw_record_status(&fw, HD_RECORD_KIND_PROFILE));
    TEST_ASSERT_EQUAL_FLOAT(0.0f, last()->ripple_nm);
    TEST_ASSERT_EQUAL_UINT32(0, hd_fw_counters(&fw)->profile_imports);
    tick_n(1000, 1000, 5);
    TEST_ASSERT_TRUE((last()->faults & HD_FAULT_PROFILE_UNUSABLE) != 0u);
    TEST_ASSERT_EQUAL_UINT32(1001, hd_fw_counters(&fw)->by_fault[HD_FAULT_BIT_PROFILE_UNUSABLE]);
    TEST_ASSERT_EQUAL_UINT8((uint8_t)status, heartbeat_profile_status());
}

static void test_profile_for_another_gear_ratio_is_refused(void)
{
    store_profile(101.0f, CPR, CPR, LINES, 3);
    check_refused(HD_RECORD_REFUSED);
}

static void test_profile_for_another_motor_encoder_is_refused(void)
{
    store_profile(100.0f, 2048u, CPR, LINES, 3);
    check_refused(HD_RECORD_REFUSED);
}

static void test_profile_for_another_output_encoder_is_refused(void)
{
    store_profile(100.0f, CPR, 16384u, LINES, 3);
    check_refused(HD_RECORD_REFUSED);
}

/* LINES peak at 1.44 N m (the sum of their amplitudes): with the correction
 * envelope below that the profile would hold the correction at its limit,
 * so it is not this joint's; at 1.5 N m it is used. */
static void test_profile_beyond_the_correction_envelope_is_refused(void)
{
    store_profile(100.0f, CPR, CPR, LINES, 3);
    cfg.kf.correction_max_nm = 1.4f;
    check_refused(HD_RECORD_REFUSED);
    store_profile(100.0f, CPR, CPR, LINES, 3);
    cfg.kf.correction_max_nm = 1.5f;
    boot_filtering();
    TEST_ASSERT_EQUAL_INT(HD_RECORD_OK, hd_fw_record_status(&fw, HD_RECORD_KIND_PROFILE));
}

static void test_profile_of_another_version_is_refused(void)
{
    uint8_t p[128];
    store_payload(p, payload(p, 100.0f, CPR, CPR, LINES, 3), HD_PROFILE_RECORD_VERSION + 1u);
    check_refused(HD_RECORD_BAD_VERSION);
}

/* The payload's offset in store copy `copy` (directory entries of 12 bytes
 * from byte 16: kind, 0, version, offset, length, CRC). */
static uint8_t *profile_payload(unsigned copy)
{
    uint8_t *c = &mock.nvm[copy * (HAL_MOCK_NVM_BYTES / 2u)];
    for (unsigned e = 0; e < c[12]; e++) {
        uint8_t *d = c + 16 + 12 * e;
        if (d[0] == HD_RECORD_KIND_PROFILE) {
            return c + (d[4] | (d[5] << 8));
        }
    }
    TEST_FAIL_MESSAGE("no profile entry");
    return NULL;
}

static void test_corrupt_profile_is_refused(void)
{
    store_profile(100.0f, CPR, CPR, LINES, 3);
    store_profile(100.0f, CPR, CPR, LINES, 3); /* both copies hold it */
    profile_payload(0)[20] ^= 0x01u;
    profile_payload(1)[30] ^= 0x40u;
    check_refused(HD_RECORD_CORRUPT);
}

static void test_one_bad_copy_still_boots_the_profile(void)
{
    with_output = true;
    store_profile(100.0f, CPR, CPR, LINES, 3);
    store_profile(100.0f, CPR, CPR, LINES, 3);
    profile_payload(1)[20] ^= 0x01u;
    boot_filtering();
    tick_n(1, 1000, 5);
    TEST_ASSERT_EQUAL_INT(HD_RECORD_ONE_COPY_BAD, hd_fw_record_status(&fw, HD_RECORD_KIND_PROFILE));
    TEST_ASSERT_DOUBLE_WITHIN(2e-5, predicted(LINES, 3, motor, outc, true),
                              (double)last()->ripple_nm);
}

/* Intact records (CRC fine) whose content cannot be a profile. */
static void test_implausible_profile_contents_are_corrupt(void)
{
    const struct {
        const char *what;
        int field; /* which mutation */
    } cases[] = {{"lock 2", 0},         {"order 0", 1},      {"a NaN", 2},
                 {"b infinite", 3},     {"9 lines", 4},      {"trailing byte", 5},
                 {"beyond the limit", 6}, {"gear ratio 0.5", 7}, {"cpr 0", 8},
                 {"load NaN", 9},       {"load 2e6 N m", 10}};
    for (unsigned i = 0; i < sizeof cases / sizeof cases[0]; i++) {
        setUp();
        line_t l[3];
        memcpy(l, LINES, sizeof l);
        float gear = 100.0f;
        uint32_t mcpr = CPR;
        switch (cases[i].field) {
        case 0: l[1].lock = 2; break;
        case 1: l[0].order = 0; break;
        case 2: l[2].a = NAN; break;
        case 3: l[1].b = INFINITY; break;
        case 6: l[0].a = 150.0f; l[0].b = 150.0f; break; /* 212 N m > 200 */
        case 7: gear = 0.5f; break;
        case 8: mcpr = 0u; break;
        default: break;
        }
        uint8_t p[128];
        size_t len = payload(p, gear, mcpr, CPR, l, 3);
        if (cases[i].field >= 9) { /* the load_nm field (payload_load's NAN means version 1) */
            const float load_nm = cases[i].field == 9 ? NAN : 2e6f;
            memcpy(p + 12, &load_nm, 4);
        }
        if (cases[i].field == 4) {
            p[16] = 9;
            len = 17u + 90u;
        }
        if (cases[i].field == 5) {
            len++;
        }
        store_payload(p, len, HD_PROFILE_RECORD_VERSION);
        printf("case %s\n", cases[i].what);
        check_refused(HD_RECORD_CORRUPT);
    }
}

static void test_missing_profile_is_no_fault(void)
{
    boot_filtering();
    tick_n(1001, 1000, 5);
    TEST_ASSERT_EQUAL_INT(HD_RECORD_MISSING, hd_fw_record_status(&fw, HD_RECORD_KIND_PROFILE));
    TEST_ASSERT_EQUAL_HEX32(0, last()->faults & HD_FAULT_PROFILE_UNUSABLE);
    TEST_ASSERT_EQUAL_UINT8(HD_RECORD_MISSING, heartbeat_profile_status());
}

/* ------------------------------------------------------- profile commands */

static hd_can_ack_t put(unsigned index, bool b, bool output, uint8_t order, float v)
{
    hd_can_cmd_t c = {0};
    c.opcode = HD_CMD_PROFILE_PUT;
    c.arg.profile_put.line = (uint8_t)(index | (b ? 0x10u : 0u) | (output ? 0x20u : 0u));
    c.arg.profile_put.order = order;
    c.arg.profile_put.value_nm = v;
    return send_cmd(&c);
}

/* A command through the bus with the output encoder ticking (send_cmd's
 * ticks have none): queued in the first tick, executed by the background,
 * live and acknowledged in the second. */
static hd_can_ack_t cmd_ticks(const hd_can_cmd_t *c)
{
    hal_can_frame_t f;
    hd_can_encode_cmd(1, c, &f);
    uint32_t before = hal_mock_tx_count(&mock);
    TEST_ASSERT_EQUAL_INT(0, hal_mock_push_rx(&mock, &f));
    tick_n(2, 1000, 5);
    hd_can_ack_t a;
    memset(&a, 0xEE, sizeof a);
    for (uint32_t i = before; i < hal_mock_tx_count(&mock); i++) {
        if (hal_mock_tx(&mock, i)->id == id_of(HD_CAN_FRAME_ACK, 1)) {
            hd_can_decode_ack(hal_mock_tx(&mock, i), &a);
        }
    }
    return a;
}

static void upload(const line_t *l, unsigned n)
{
    for (unsigned i = 0; i < n; i++) {
        bool o = l[i].lock == HD_KF_LOCK_OUTPUT;
        TEST_ASSERT_EQUAL_UINT8(HD_CAN_RES_OK, put(i, false, o, l[i].order, l[i].a).result);
        TEST_ASSERT_EQUAL_UINT8(HD_CAN_RES_OK, put(i, true, o, l[i].order, l[i].b).result);
    }
}

/* The stored record's load_nm, as stored_lines last read it. */
static float stored_load_nm;

/* Reads the stored record and parses it by the documented layout. */
static unsigned stored_lines(line_t *l, float *gear)
{
    hd_store_io_t s = storage();
    uint8_t p[128];
    size_t len = 0;
    int st = hd_store_load(&s, HD_RECORD_KIND_PROFILE, HD_PROFILE_RECORD_VERSION, p, sizeof p, &len,
                           NULL, NULL);
    if (st == HD_RECORD_MISSING) {
        return 0u;
    }
    TEST_ASSERT_EQUAL_INT(HD_RECORD_OK, st);
    memcpy(gear, p, 4);
    memcpy(&stored_load_nm, p + 12, 4);
    unsigned n = p[16];
    TEST_ASSERT_EQUAL_UINT(17u + 10u * n, len);
    for (unsigned i = 0; i < n; i++) {
        l[i].lock = p[17 + 10 * i];
        l[i].order = p[18 + 10 * i];
        memcpy(&l[i].a, p + 19 + 10 * i, 4);
        memcpy(&l[i].b, p + 23 + 10 * i, 4);
    }
    return n;
}

static void test_upload_load_save_and_clear(void)
{
    with_output = true;
    boot_filtering();
    tick_n(20, 1000, 5);
    upload(LINES, 3);
    hd_can_cmd_t c = {0};
    c.opcode = HD_CMD_PROFILE_LOAD;
    c.arg.profile_load.source = 1; /* the uploaded lines, into the running filter */
    hd_can_ack_t a = cmd_ticks(&c);
    TEST_ASSERT_EQUAL_UINT8(HD_CAN_RES_OK, a.result);
    TEST_ASSERT_EQUAL_FLOAT(3.0f, a.value);
    /* taken before the step of the tick after the command: its prediction */
    TEST_ASSERT_DOUBLE_WITHIN(2e-5, predicted(LINES, 3, motor, outc, true), (double)last()->ripple_nm);
    /* saved as uploaded */
    c.opcode = HD_CMD_PROFILE_SAVE;
    c.arg.profile_save.source = 1;
    a = send_cmd(&c);
    TEST_ASSERT_EQUAL_UINT8(HD_CAN_RES_OK, a.result);
    TEST_ASSERT_EQUAL_UINT8(HD_RECORD_OK, a.aux);
    line_t back[8];
    float gear = 0.0f;
    TEST_ASSERT_EQUAL_UINT(3, stored_lines(back, &gear));
    TEST_ASSERT_EQUAL_FLOAT(100.0f, gear);
    for (unsigned i = 0; i < 3; i++) {
        TEST_ASSERT_EQUAL_UINT8(LINES[i].lock, back[i].lock);
        TEST_ASSERT_EQUAL_UINT8(LINES[i].order, back[i].order);
        TEST_ASSERT_EQUAL_FLOAT(LINES[i].a, back[i].a);
        TEST_ASSERT_EQUAL_FLOAT(LINES[i].b, back[i].b);
    }
    tick_n(1000, 1000, 5);
    TEST_ASSERT_EQUAL_UINT8(HD_RECORD_OK, heartbeat_profile_status());
    /* cleared: no record, the running filter keeps its state (the motor
     * order-2 line's amplitude: the ripple itself passes through zero) */
    const float before = hd_kf_block_amplitude_nm(&live_pipe()->kf, 0);
    c.opcode = HD_CMD_PROFILE_CLEAR;
    a = send_cmd(&c);
    TEST_ASSERT_EQUAL_UINT8(HD_CAN_RES_OK, a.result);
    TEST_ASSERT_EQUAL_UINT(0, stored_lines(back, &gear));
    TEST_ASSERT_EQUAL_INT(HD_RECORD_MISSING, hd_fw_record_status(&fw, HD_RECORD_KIND_PROFILE));
    TEST_ASSERT_TRUE(before > 0.05f);
    TEST_ASSERT_FLOAT_WITHIN(0.01f, before, hd_kf_block_amplitude_nm(&live_pipe()->kf, 0));
    /* and the next restart is from zero */
    c.opcode = HD_CMD_FILTER_RESET;
    send_cmd(&c);
    TEST_ASSERT_EQUAL_FLOAT(0.0f, last()->ripple_nm);
}

static void test_restarts_start_from_the_profile(void)
{
    with_output = true;
    store_profile(100.0f, CPR, CPR, LINES, 3);
    boot_filtering();
    tick_n(50, 1000, 5);
    /* a rebuild: the new filter takes the profile at its first sample */
    hd_can_cmd_t c = {0};
    c.opcode = HD_CMD_SET_PARAM;
    c.arg.set_param.id = HD_PARAM_R_NM2;
    c.arg.set_param.value = 0.01f;
    hal_can_frame_t f;
    hd_can_encode_cmd(1, &c, &f);
    hal_mock_push_rx(&mock, &f);
    unsigned imports = hd_fw_counters(&fw)->profile_imports;
    tick_n(1, 1000, 5); /* queued, executed */
    tick_n(1, 1000, 5); /* swapped and imported */
    TEST_ASSERT_EQUAL_FLOAT(0.01f, live_pipe()->kf.cfg.r_nm2);
    TEST_ASSERT_EQUAL_UINT32(imports + 1u, hd_fw_counters(&fw)->profile_imports);
    TEST_ASSERT_DOUBLE_WITHIN(2e-5, predicted(LINES, 3, motor, outc, true), (double)last()->ripple_nm);
    /* FILTER_RESET likewise */
    c.opcode = HD_CMD_FILTER_RESET;
    hd_can_encode_cmd(1, &c, &f);
    hal_mock_push_rx(&mock, &f);
    tick_n(2, 1000, 5);
    TEST_ASSERT_EQUAL_UINT32(imports + 2u, hd_fw_counters(&fw)->profile_imports);
    TEST_ASSERT_DOUBLE_WITHIN(2e-5, predicted(LINES, 3, motor, outc, true), (double)last()->ripple_nm);
}

static void test_loading_a_refused_record_changes_nothing(void)
{
    with_output = true;
    store_profile(100.0f, CPR, CPR, LINES, 3);
    boot_filtering();
    tick_n(10, 1000, 5);
    store_profile(50.0f, CPR, CPR, LINES, 2);
    hd_can_cmd_t c = {0};
    c.opcode = HD_CMD_PROFILE_LOAD;
    hd_can_ack_t a = send_cmd(&c);
    TEST_ASSERT_EQUAL_UINT8(HD_CAN_RES_REJECTED, a.result);
    TEST_ASSERT_EQUAL_UINT8(HD_RECORD_REFUSED, a.aux);
    TEST_ASSERT_EQUAL_UINT8(3, fw.bg.profile.line_count); /* the booted profile stays */
    TEST_ASSERT_EQUAL_INT(HD_RECORD_OK, hd_fw_record_status(&fw, HD_RECORD_KIND_PROFILE));
    /* a good one loads (2 lines) */
    store_profile(100.0f, CPR, CPR, LINES, 2);
    a = send_cmd(&c);
    TEST_ASSERT_EQUAL_UINT8(HD_CAN_RES_OK, a.result);
    TEST_ASSERT_EQUAL_FLOAT(2.0f, a.value);
    /* none stored */
    c.opcode = HD_CMD_PROFILE_CLEAR;
    TEST_ASSERT_EQUAL_UINT8(HD_CAN_RES_OK, send_cmd(&c).result);
    c.opcode = HD_CMD_PROFILE_LOAD;
    a = send_cmd(&c);
    TEST_ASSERT_EQUAL_UINT8(HD_CAN_RES_NO_DATA, a.result);
    TEST_ASSERT_EQUAL_UINT8(HD_RECORD_MISSING, a.aux);
}

static void test_bad_uploads_are_refused(void)
{
    init_fw();
    TEST_ASSERT_EQUAL_UINT8(HD_CAN_RES_BAD_INDEX, put(8, false, false, 2, 0.1f).result);
    hd_can_cmd_t c = {0};
    c.opcode = HD_CMD_PROFILE_PUT;
    c.arg.profile_put.line = 0x40;
    c.arg.profile_put.order = 2;
    TEST_ASSERT_EQUAL_UINT8(HD_CAN_RES_BAD_INDEX, send_cmd(&c).result);
    TEST_ASSERT_EQUAL_UINT8(HD_CAN_RES_BAD_INDEX, put(0, true, false, 2, 0.1f).result); /* b first */
    TEST_ASSERT_EQUAL_UINT8(HD_CAN_RES_OUT_OF_RANGE, put(0, false, false, 0, 0.1f).result);
    TEST_ASSERT_EQUAL_UINT8(HD_CAN_RES_NOT_FINITE, put(0, false, false, 2, NAN).result);
    TEST_ASSERT_EQUAL_UINT8(HD_CAN_RES_OUT_OF_RANGE, put(0, false, false, 2, 250.0f).result);
    TEST_ASSERT_EQUAL_UINT8(HD_CAN_RES_OK, put(0, false, false, 2, 0.1f).result);
    TEST_ASSERT_EQUAL_UINT8(HD_CAN_RES_BAD_INDEX, put(0, true, false, 4, 0.1f).result); /* other order */
    TEST_ASSERT_EQUAL_UINT8(HD_CAN_RES_BAD_INDEX, put(0, true, true, 2, 0.1f).result);  /* other lock */
    TEST_ASSERT_EQUAL_UINT8(HD_CAN_RES_BAD_INDEX, put(1, false, false, 4, 0.1f).result); /* line 0 open */
    /* incomplete: nothing to load or save */
    c = (hd_can_cmd_t){0};
    c.opcode = HD_CMD_PROFILE_LOAD;
    c.arg.profile_load.source = 1;
    TEST_ASSERT_EQUAL_UINT8(HD_CAN_RES_NO_DATA, send_cmd(&c).result);
    c.opcode = HD_CMD_PROFILE_SAVE;
    c.arg.profile_save.source = 1;
    TEST_ASSERT_EQUAL_UINT8(HD_CAN_RES_NO_DATA, send_cmd(&c).result);
    c.arg.profile_save.source = 2;
    TEST_ASSERT_EQUAL_UINT8(HD_CAN_RES_OUT_OF_RANGE, send_cmd(&c).result);
    c.opcode = HD_CMD_PROFILE_LOAD;
    c.arg.profile_load.source = 2;
    TEST_ASSERT_EQUAL_UINT8(HD_CAN_RES_OUT_OF_RANGE, send_cmd(&c).result);
}

/* PROFILE_SAVE of the running filter: the saved line of each block turned
 * to the absolute angle of the snapshot's sample is the block's state then. */
static void test_snapshot_save_is_the_filter_at_a_tick_boundary(void)
{
    with_output = true;
    store_profile(100.0f, CPR, CPR, LINES, 3);
    boot_filtering();
    tick_n(200, 1300, 7); /* the filter learns something of its own */
    hd_can_cmd_t c = {0};
    c.opcode = HD_CMD_PROFILE_SAVE;
    c.token = 0x5A;
    hal_can_frame_t f;
    hd_can_encode_cmd(1, &c, &f);
    hal_mock_push_rx(&mock, &f);
    const uint32_t seq0 = fw.filter.snapshot_seq;
    float x[3][2] = {{0}};
    float load_nm = -2.0f;
    uint32_t at_m = 0, at_o = 0;
    hd_can_ack_t a;
    memset(&a, 0xEE, sizeof a);
    for (unsigned i = 0; i < 6 && a.token != 0x5A; i++) {
        uint32_t before = hal_mock_tx_count(&mock);
        tick_n(1, 1300, 7);
        if (fw.filter.snapshot_seq != seq0 && at_m == 0u) {
            at_m = motor;
            at_o = outc;
            /* the state after the step is the estimate at this sample's
             * angle (hd_kf.h, "Which angle") */
            for (unsigned s = 0; s < 3; s++) {
                x[s][0] = hd_kf_state(&live_pipe()->kf, 2 * s);
                x[s][1] = hd_kf_state(&live_pipe()->kf, 2 * s + 1);
            }
            const hd_kf_t *kf = &live_pipe()->kf;
            load_nm = kf->learn_load_weight > 0.0f ? kf->learn_load_nm / kf->learn_load_weight
                                                   : -1.0f; /* hd_kf.h: none learned */
        }
        for (uint32_t k = before; k < hal_mock_tx_count(&mock); k++) {
            if (hal_mock_tx(&mock, k)->id == id_of(HD_CAN_FRAME_ACK, 1)) {
                hd_can_decode_ack(hal_mock_tx(&mock, k), &a);
            }
        }
    }
    TEST_ASSERT_EQUAL_UINT8(HD_CMD_PROFILE_SAVE, a.opcode);
    TEST_ASSERT_EQUAL_UINT8(HD_CAN_RES_OK, a.result);
    TEST_ASSERT_EQUAL_FLOAT(3.0f, a.value);
    line_t back[8];
    float gear;
    TEST_ASSERT_EQUAL_UINT(3, stored_lines(back, &gear));
    /* recommended model: motor 2, motor 4, output 1, in that order */
    for (unsigned s = 0; s < 3; s++) {
        const bool o = back[s].lock == HD_KF_LOCK_OUTPUT;
        TEST_ASSERT_EQUAL_UINT8(LINES[s].lock, back[s].lock);
        TEST_ASSERT_EQUAL_UINT8(LINES[s].order, back[s].order);
        double k_alpha = back[s].order * 2.0 * TEST_PI * (double)((o ? at_o : at_m) % CPR) / CPR;
        double x1 = (double)back[s].a * cos(k_alpha) + (double)back[s].b * sin(k_alpha);
        double x2 = -(double)back[s].a * sin(k_alpha) + (double)back[s].b * cos(k_alpha);
        TEST_ASSERT_DOUBLE_WITHIN(2e-5, (double)x[s][0], x1);
        TEST_ASSERT_DOUBLE_WITHIN(2e-5, (double)x[s][1], x2);
    }
    /* the filter has moved away from the booted profile: this saved its own */
    TEST_ASSERT_TRUE(fabsf(back[0].a - LINES[0].a) + fabsf(back[0].b - LINES[0].b) > 1e-3f);
    /* and the load its motor lines were learned at, at the same tick */
    TEST_ASSERT_TRUE(load_nm != -2.0f);
    TEST_ASSERT_EQUAL_FLOAT(load_nm, stored_load_nm);
}

/* Operating mode with a learn scale of 0: output-locked blocks keep the
 * profile whatever the torque does; motor-locked ones keep learning. */
static void learn_and_save(uint8_t mode, line_t *back)
{
    setUp();
    with_output = true;
    cfg.learning_mode = mode;
    cfg.operating_output_learn_scale = 0.0f;
    store_profile(100.0f, CPR, CPR, LINES, 3);
    boot_filtering();
    /* a slow load while the output turns (0.6 counts a tick): enough motion
     * for the data to tell an output line from the offset */
    for (unsigned i = 0; i < 3000; i++) {
        tick_n(1, 1000 + (int32_t)(400.0 * sin(i * 0.003)), 60);
    }
    hd_can_cmd_t c = {0};
    c.opcode = HD_CMD_PROFILE_SAVE;
    hal_can_frame_t f;
    hd_can_encode_cmd(1, &c, &f);
    hal_mock_push_rx(&mock, &f);
    tick_n(4, 1000, 60);
    float gear;
    TEST_ASSERT_EQUAL_UINT(3, stored_lines(back, &gear));
}

static void test_operating_mode_freezes_output_lines(void)
{
    line_t op[8], com[8];
    learn_and_save(HD_FW_LEARN_OPERATING, op);
    TEST_ASSERT_EQUAL_FLOAT(0.0f, live_pipe()->kf.cfg.output_learn_scale);
    TEST_ASSERT_DOUBLE_WITHIN(1e-5, LINES[2].a, op[2].a);
    TEST_ASSERT_DOUBLE_WITHIN(1e-5, LINES[2].b, op[2].b);
    TEST_ASSERT_TRUE(fabsf(op[0].a - LINES[0].a) > 1e-3f); /* motor 2 learned */
    learn_and_save(HD_FW_LEARN_ADAPTIVE, com);
    TEST_ASSERT_EQUAL_FLOAT(1.0f, live_pipe()->kf.cfg.output_learn_scale);
    TEST_ASSERT_TRUE(fabsf(com[2].a - LINES[2].a) + fabsf(com[2].b - LINES[2].b) > 1e-2f);
    /* commissioning: output lines at full rate, the offset 100x slower */
    line_t bench[8];
    learn_and_save(HD_FW_LEARN_COMMISSIONING, bench);
    TEST_ASSERT_EQUAL_FLOAT(1.0f, live_pipe()->kf.cfg.output_learn_scale);
    TEST_ASSERT_EQUAL_FLOAT(0.01f * cfg.kf.offset_q_nm2, live_pipe()->kf.cfg.offset_q_nm2);
    TEST_ASSERT_EQUAL_FLOAT(cfg.kf.offset_q_nm2, live_cfg()->kf.offset_q_nm2); /* the setting */
}

/* The profile's lines against slow motion (q_motion_ref_profiled_rad,
 * default 0.15 rad): only in operating mode and only once the stored profile
 * is imported (again after a restart).  Read as the motor increment from
 * which the order-2 block learns at its full rate: reference / 2. */
static float order2_full_rad(void)
{
    return live_pipe()->kf.slot[0].full_rad;
}

static void test_profiled_reference_in_operating_mode_only(void)
{
    const float shared = cfg.kf.q_motion_ref_rad / 2.0f;
    const float held = cfg.kf.q_motion_ref_profiled_rad / 2.0f;
    TEST_ASSERT_FLOAT_WITHIN(1e-6f, 0.075f, held); /* the row's default */
    static const uint8_t modes[] = {HD_FW_LEARN_OPERATING, HD_FW_LEARN_ADAPTIVE,
                                    HD_FW_LEARN_COMMISSIONING};
    for (unsigned m = 0; m < 3u; m++) {
        for (unsigned stored = 0; stored < 2u; stored++) {
            setUp();
            with_output = true;
            cfg.learning_mode = modes[m];
            if (stored) {
                store_profile(100.0f, CPR, CPR, LINES, 3);
            }
            boot_filtering();
            tick_n(1, 1000, 5);
            const bool on = stored && modes[m] == HD_FW_LEARN_OPERATING;
            TEST_ASSERT_FLOAT_WITHIN(1e-6f, on ? held : shared, order2_full_rad());
            /* a restart: from zero, then the stored profile again */
            hd_can_cmd_t c = {0};
            c.opcode = HD_CMD_FILTER_RESET;
            send_cmd(&c);
            tick_n(1, 1000, 5);
            TEST_ASSERT_FLOAT_WITHIN(1e-6f, on ? held : shared, order2_full_rad());
        }
    }
}

/* A speed change with the exact profile in the data: the filter turns by
 * each sample's own increment before predicting it, so it keeps predicting
 * the ripple at each sample's angle through the change (before it turned
 * by the increment passed with the previous sample and lagged by order x
 * the change: 0.12 N m here, docs/design/slow-torque.md "Increment prediction"). */
static void test_the_filter_keeps_the_phase_through_a_speed_change(void)
{
    with_output = true;
    cfg.learning_mode = HD_FW_LEARN_OPERATING;
    store_profile(100.0f, CPR, CPR, LINES, 3);
    boot_filtering();
    double worst = 0.0, worst_lagged = 0.0;
    for (unsigned i = 0; i < 600; i++) {
        const uint32_t step = i < 300 ? 20u : 60u;
        /* the torque this sample will carry: 2 N m + the profile's ripple */
        double t = 2.0 + predicted(LINES, 3, motor + step, (motor + step) / 100u, true);
        int32_t counts = (int32_t)lround((t / GAIN + OFFSET_V) / VPC);
        tick_n(1, counts, step);
        if (i >= 300 && i < 310) {
            /* the old filter predicted each sample after the change at the
             * old speed's angle, 40 counts behind, until it relearned */
            const uint32_t lagged_m = motor - 40u;
            const double e = fabs(predicted(LINES, 3, lagged_m, lagged_m / 100u, true) -
                                  predicted(LINES, 3, motor, outc, true));
            worst_lagged = e > worst_lagged ? e : worst_lagged;
        }
        if (i >= 300 || (i >= 2 && i < 30)) { /* from the change on, and after boot */
            double e = fabs((double)last()->ripple_nm - predicted(LINES, 3, motor, outc, true));
            worst = e > worst ? e : worst;
        }
    }
    printf("speed change 20 -> 60 counts/tick: worst ripple error %.4f N m (a prediction "
           "at the old speed's angle would be %.4f N m off)\n", worst, worst_lagged);
    TEST_ASSERT_TRUE(worst < 0.01);        /* ADC step 2 mN m, learning on it */
    TEST_ASSERT_TRUE(worst_lagged > 0.05); /* order 2: 2 x 0.06 rad on 0.8 N m */
}

static void test_profile_record_version_is_reported(void)
{
    init_fw();
    hd_can_ack_t a = simple_cmd(HD_CMD_VERSION, HD_INFO_PROFILE_RECORD_VERSION);
    TEST_ASSERT_EQUAL_UINT8(HD_CAN_RES_OK, a.result);
    TEST_ASSERT_EQUAL_UINT32(HD_PROFILE_RECORD_VERSION, a.value_u32);
}

int main(int argc, char **argv)
{
    if (UnityParseOptions(argc, argv) != 0) {
        return 1;
    }
    UNITY_BEGIN();
    RUN_TEST(test_feedforward_is_latched_into_t_exp_and_goes_stale_with_a_ramp);
    RUN_TEST(test_a_stale_ramp_of_zero_drops_at_once_and_none_received_is_stale);
    RUN_TEST(test_bad_feedforward_frames_are_flagged_and_never_fed);
    RUN_TEST(test_no_feedforward_expected_ignores_frames);
    RUN_TEST(test_motor_current_enters_t_exp_and_a_bad_reading_holds);
    RUN_TEST(test_motor_current_low_pass);
    RUN_TEST(test_motor_current_lag_is_extrapolated_away);
    RUN_TEST(test_motor_current_variance_at_standstill_and_speed);
    RUN_TEST(test_no_current_channel);
    RUN_TEST(test_boot_predicts_the_stored_profile_from_the_first_sample);
    RUN_TEST(test_profile_load_reaches_the_filter_and_version_1_still_boots);
    RUN_TEST(test_without_an_output_encoder_output_lines_are_not_used);
    RUN_TEST(test_profile_for_another_gear_ratio_is_refused);
    RUN_TEST(test_profile_for_another_motor_encoder_is_refused);
    RUN_TEST(test_profile_for_another_output_encoder_is_refused);
    RUN_TEST(test_profile_beyond_the_correction_envelope_is_refused);
    RUN_TEST(test_profile_of_another_version_is_refused);
    RUN_TEST(test_corrupt_profile_is_refused);
    RUN_TEST(test_one_bad_copy_still_boots_the_profile);
    RUN_TEST(test_implausible_profile_contents_are_corrupt);
    RUN_TEST(test_missing_profile_is_no_fault);
    RUN_TEST(test_upload_load_save_and_clear);
    RUN_TEST(test_restarts_start_from_the_profile);
    RUN_TEST(test_loading_a_refused_record_changes_nothing);
    RUN_TEST(test_bad_uploads_are_refused);
    RUN_TEST(test_snapshot_save_is_the_filter_at_a_tick_boundary);
    RUN_TEST(test_operating_mode_freezes_output_lines);
    RUN_TEST(test_profiled_reference_in_operating_mode_only);
    RUN_TEST(test_the_filter_keeps_the_phase_through_a_speed_change);
    RUN_TEST(test_profile_record_version_is_reported);
    return UNITY_END();
}
