/*
 * The firmware's control stage (hd_fw_control.c) on the mock HAL with a
 * recording drive: what reaches the drive, when, and what is refused.
 *   - the watchdog reaches DAMP at ctrl_watchdog_ms after the last new
 *     setpoint (within timeout + 1 tick), STOP ctrl_damp_ms later, with its
 *     fault bit; a repeated sequence number does not feed it;
 *   - bad input (unknown mode, beyond the torque limit or the position
 *     window, a "not a number" field, non-finite or absurd gains, a short
 *     frame, another node's frame) is refused with an ACK status and a fault
 *     bit and never reaches the drive;
 *   - no command ever exceeds ctrl_current_limit_a or is not finite, for a
 *     wound-up loop and for 20000 ticks of random frames, gauge readings,
 *     sensor faults, deadline misses and speeds;
 *   - each fault reaction, timed from the first faulty tick: encoder lost ->
 *     STOP latched until a STOP setpoint; gauge unusable (ADC error,
 *     saturated, open bridge, beyond range) and a real filter restart ->
 *     DAMP; filter frozen -> no reaction; drive fault or a failed drive
 *     call -> STOP latched; bus-off and repeated deadline misses -> DAMP;
 *   - a board without a drive sends nothing new and refuses control modes.
 * The `measured:` lines are the control table of docs/results/reliability.md
 * (tests/reliability/rel_doc.py); the expectations are the reactions
 * docs/design/firmware.md specifies, not what the code happens to do.
 */
#include <math.h>
#include <stdio.h>

#include "fw_drive_rig.h"

void setUp(void) {}
void tearDown(void) {}

/* The last SETPOINT_REFUSED ACK since `from` (result 0xEE if none). */
static hd_can_ack_t refusal_since(uint32_t from)
{
    hd_can_ack_t a;
    memset(&a, 0xEE, sizeof a);
    for (uint32_t i = from; i < hal_mock_tx_count(&mock); i++) {
        hd_can_ack_t x;
        if (hd_can_decode_ack(hal_mock_tx(&mock, i), &x) == 0 && x.opcode == HD_CMD_SETPOINT_REFUSED) {
            a = x;
        }
    }
    return a;
}

static hd_ctrl_mode_t mode_run(void)
{
    return fw.control.out.mode;
}

/* ------------------------------------------------------------- tests */

static void test_watchdog_damp_then_stop(void)
{
    start(true);
    setpoint_tick(HD_CTRL_TORQUE, 2.0f);
    const uint32_t t0 = fw.counters.ticks; /* the setpoint's tick is t0 - 1 + 1 */
    TEST_ASSERT_EQUAL_INT(HD_CTRL_TORQUE, mode_run());
    TEST_ASSERT_TRUE(drv.enabled);
    const unsigned timeout = live_cfg()->ctrl_watchdog_ms, damp = live_cfg()->ctrl_damp_ms;
    int damp_at = -1, stop_at = -1;
    bool fault_seen = false;
    uint32_t faults = 0u;
    for (unsigned n = 1; n <= timeout + damp + 5u; n++) {
        /* the same sequence number again: stale, it does not feed the watchdog */
        push_setpoint(HD_CTRL_TORQUE, 2.0f, 0.0f, (uint8_t)(seq_next - 1u));
        run(1, counts_of(0.0), 1);
        fault_seen |= (fw.last.faults & HD_FAULT_CTRL_WATCHDOG) != 0u;
        faults |= fw.last.faults;
        if (damp_at < 0 && mode_run() == HD_CTRL_DAMP) {
            damp_at = (int)(fw.counters.ticks - t0);
        }
        if (stop_at < 0 && mode_run() == HD_CTRL_STOP) {
            stop_at = (int)(fw.counters.ticks - t0);
        }
    }
    printf("measured: ctrl_watchdog timeout_ms=%u damp_ms=%u damp_ticks=%d stop_ticks=%d "
           "faults=%x\n", timeout, damp, damp_at, stop_at, faults);
    TEST_ASSERT_TRUE(fault_seen);
    TEST_ASSERT_TRUE(damp_at >= (int)timeout && damp_at <= (int)timeout + 1);
    TEST_ASSERT_TRUE(stop_at >= (int)(timeout + damp) && stop_at <= (int)(timeout + damp) + 1);
    TEST_ASSERT_FALSE(drv.enabled);
    /* a new setpoint resumes */
    setpoint_tick(HD_CTRL_TORQUE, 2.0f);
    TEST_ASSERT_EQUAL_INT(HD_CTRL_TORQUE, mode_run());
    TEST_ASSERT_TRUE(drv.enabled);
}

static void test_fresh_setpoints_keep_the_mode(void)
{
    start(true);
    for (unsigned n = 0; n < 300u; n++) {
        setpoint_tick(HD_CTRL_TORQUE, 1.0f);
        TEST_ASSERT_EQUAL_INT(HD_CTRL_TORQUE, mode_run());
    }
    TEST_ASSERT_EQUAL_UINT32(0u, fw.counters.by_fault[HD_FAULT_BIT_CTRL_WATCHDOG]);
}

typedef struct {
    const char *what;
    uint8_t mode;
    float torque_nm;
    float position_rad;
    bool na_torque;       /* the "not a number" int16 */
    int result;
} bad_setpoint_t;

static void test_bad_setpoints_refused_never_reach_the_drive(void)
{
    const bad_setpoint_t cases[] = {
        {"unknown mode", 7u, 0.0f, 0.0f, false, HD_CAN_RES_OUT_OF_RANGE},
        {"beyond the torque limit", HD_CTRL_TORQUE, 45.0f, 0.0f, false, HD_CAN_RES_OUT_OF_RANGE},
        {"beyond the position window", HD_CTRL_IMPEDANCE, 0.0f, 2.0f, false,
         HD_CAN_RES_OUT_OF_RANGE},
        {"not a number", HD_CTRL_TORQUE, 0.0f, 0.0f, true, HD_CAN_RES_NOT_FINITE},
    };
    for (size_t i = 0; i < sizeof cases / sizeof cases[0]; i++) {
        start(true);
        const uint32_t from = hal_mock_tx_count(&mock);
        const hd_can_setpoint_t sp = {cases[i].mode, 0x42u, cases[i].torque_nm,
                                      cases[i].position_rad, 0.0f};
        hal_can_frame_t f;
        hd_can_encode_setpoint(live_cfg()->node_id, &sp, &f);
        if (cases[i].na_torque) {
            f.data[2] = 0x00u;
            f.data[3] = 0x80u;
        }
        hal_mock_push_rx(&mock, &f);
        run(3, counts_of(0.0), 1);
        const hd_can_ack_t a = refusal_since(from);
        TEST_ASSERT_EQUAL_INT_MESSAGE(cases[i].result, a.result, cases[i].what);
        TEST_ASSERT_EQUAL_UINT8_MESSAGE(0x42u, a.token, cases[i].what);
        TEST_ASSERT_EQUAL_UINT32_MESSAGE(1u, fw.counters.by_fault[HD_FAULT_BIT_SETPOINT_REFUSED],
                                         cases[i].what);
        TEST_ASSERT_EQUAL_UINT32_MESSAGE(0u, drv.enables, cases[i].what);
        TEST_ASSERT_EQUAL_UINT32_MESSAGE(0u, drv.commands, cases[i].what);
        TEST_ASSERT_EQUAL_INT_MESSAGE(HD_CTRL_STOP, mode_run(), cases[i].what);
        printf("%s%d", i == 0 ? "measured: ctrl_setpoint_refused results=" : ",", a.result);
    }
    printf(" cases=%u commands=0\n", (unsigned)(sizeof cases / sizeof cases[0]));
}

static void push_gains(float kp, float kd)
{
    const hd_can_gains_t g = {kp, kd};
    hal_can_frame_t f;
    hd_can_encode_gains(live_cfg()->node_id, &g, &f);
    hal_mock_push_rx(&mock, &f);
}

static void test_bad_gains_short_frames_and_other_nodes(void)
{
    start(true);
    const float bad[][2] = {{NAN, 0.0f}, {0.0f, INFINITY}, {HD_CTRL_KP_MAX_NM_RAD * 2.0f, 0.0f},
                            {10.0f, -1.0f}};
    const int want[] = {HD_CAN_RES_NOT_FINITE, HD_CAN_RES_NOT_FINITE, HD_CAN_RES_OUT_OF_RANGE,
                        HD_CAN_RES_OUT_OF_RANGE};
    for (size_t i = 0; i < 4; i++) {
        const uint32_t from = hal_mock_tx_count(&mock);
        push_gains(bad[i][0], bad[i][1]);
        run(1, counts_of(0.0), 1);
        const hd_can_ack_t a = refusal_since(from);
        TEST_ASSERT_EQUAL_INT(want[i], a.result);
        TEST_ASSERT_EQUAL_UINT8(1u, a.aux);
    }
    TEST_ASSERT_EQUAL_FLOAT(0.0f, fw.control.kp_nm_rad);
    TEST_ASSERT_EQUAL_FLOAT(0.0f, fw.control.kd_nm_s_rad);
    /* a short SETPOINT */
    uint32_t from = hal_mock_tx_count(&mock);
    hal_can_frame_t f;
    const hd_can_setpoint_t sp = {HD_CTRL_TORQUE, 9u, 1.0f, 0.0f, 0.0f};
    hd_can_encode_setpoint(live_cfg()->node_id, &sp, &f);
    f.len = 6u;
    hal_mock_push_rx(&mock, &f);
    run(1, counts_of(0.0), 1);
    TEST_ASSERT_EQUAL_INT(HD_CAN_RES_BAD_LENGTH, refusal_since(from).result);
    /* another node's SETPOINT: not ours, counted, no ACK, no drive */
    from = hal_mock_tx_count(&mock);
    const uint32_t foreign = fw.counters.foreign_frames;
    hd_can_encode_setpoint((uint8_t)(live_cfg()->node_id + 1u), &sp, &f);
    hal_mock_push_rx(&mock, &f);
    run(1, counts_of(0.0), 1);
    TEST_ASSERT_EQUAL_UINT32(foreign + 1u, fw.counters.foreign_frames);
    TEST_ASSERT_EQUAL_UINT8(0xEEu, refusal_since(from).opcode);
    TEST_ASSERT_EQUAL_UINT32(0u, drv.commands);
    /* good gains are taken */
    push_gains(120.0f, 1.5f);
    run(1, counts_of(0.0), 1);
    TEST_ASSERT_EQUAL_FLOAT(120.0f, fw.control.kp_nm_rad);
}

/* The gauge reads 0 N m whatever the drive does: the loop's integral winds
 * to the current limit, which no command exceeds. */
static void test_current_never_beyond_its_limit(void)
{
    start(true);
    for (unsigned n = 0; n < 1500u; n++) {
        setpoint_tick(HD_CTRL_TORQUE, 39.0f);
    }
    printf("measured: ctrl_current_limit setpoint_nm=39 max_abs_a=%.4f limit_a=%.4f\n",
           (double)drv.max_abs_a, (double)live_cfg()->ctrl.current_limit_a);
    TEST_ASSERT_FLOAT_WITHIN(1e-6, live_cfg()->ctrl.current_limit_a, drv.max_abs_a);
    TEST_ASSERT_TRUE(fw.control.out.limits & HD_CTRL_LIM_CURRENT);
}

/* ------------------------------------------------- fault reactions
 * Each reaction is timed: ticks from the first tick whose input carries the
 * fault to the first tick whose command ran the safe mode (0: the command
 * of the faulty tick itself), and the ticks back to the asked mode once the
 * fault is gone.  The measured: lines are the control table of
 * docs/results/reliability.md (tests/reliability/rel_doc.py). */

static hal_mock_sample_t fault_smp; /* what the next sample_tick reads */

/* One tick with a new TORQUE setpoint and the sample fault_smp (the motor
 * moving `step` counts per tick unless the sample says otherwise). */
static void sample_tick(float torque_nm, uint32_t step)
{
    push_setpoint(HD_CTRL_TORQUE, torque_nm, 0.0f, seq_next++);
    motor += step;
    hal_mock_sample_t smp = fault_smp;
    smp.enc.motor_counts = motor;
    TEST_ASSERT_EQUAL_INT(0, hal_mock_push_sample(&mock, &smp));
    hd_fw_isr(&fw);
    hd_fw_background(&fw);
}

static void healthy_sample(int32_t counts)
{
    memset(&fault_smp, 0, sizeof fault_smp);
    fault_smp.adc.bridge_counts = counts;
}

/* Runs sample_tick until the command runs `want` (STOP: until the drive is
 * disabled), at most max ticks: the tick index (0 = the first), -1 if it
 * never did.  *faults collects the fault bits of those ticks. */
static int ticks_until(hd_ctrl_mode_t want, unsigned max, float torque_nm, uint32_t *faults)
{
    for (unsigned i = 0; i < max; i++) {
        sample_tick(torque_nm, 1u);
        *faults |= fw.last.faults;
        if (want == HD_CTRL_STOP ? !drv.enabled : mode_run() == want) {
            return (int)i;
        }
    }
    return -1;
}

/* Settled in TORQUE on a healthy gauge (the setpoint's torque measured). */
static void settle_torque(void)
{
    healthy_sample(counts_of(1.0));
    for (int i = 0; i < 20; i++) {
        sample_tick(1.0f, 1u);
    }
    TEST_ASSERT_EQUAL_INT(HD_CTRL_TORQUE, mode_run());
}

/* A latched STOP is released by a STOP setpoint: ticks from it back to TORQUE. */
static int release_latched_stop(void)
{
    setpoint_tick(HD_CTRL_STOP, 0.0f);
    uint32_t ignored = 0u;
    return 1 + ticks_until(HD_CTRL_TORQUE, 5u, 1.0f, &ignored);
}

static void test_reaction_encoder_lost(void)
{
    start(true);
    settle_torque();
    fault_smp.enc.fault = true;
    uint32_t faults = 0u;
    const int react = ticks_until(HD_CTRL_STOP, 10u, 1.0f, &faults);
    TEST_ASSERT_EQUAL_INT(0, react);
    TEST_ASSERT_FALSE(drv.enabled);
    TEST_ASSERT_TRUE(faults & HD_FAULT_ENC_FAULT);
    TEST_ASSERT_TRUE(faults & HD_FAULT_CTRL_FALLBACK);
    healthy_sample(counts_of(1.0));
    for (int i = 0; i < 50; i++) { /* encoder back: still latched */
        sample_tick(1.0f, 1u);
        TEST_ASSERT_EQUAL_INT(HD_CTRL_STOP, mode_run());
    }
    const int resume = release_latched_stop();
    TEST_ASSERT_EQUAL_INT(1, resume);
    TEST_ASSERT_TRUE(drv.enabled);
    printf("measured: ctrl_encoder_lost reaction_ticks=%d limit_ticks=0 faults=%x "
           "latched_ticks=50 resume_ticks=%d\n", react, faults, resume);
}

typedef struct {
    const char *name;
    int adc_rc;
    bool saturated;
    double torque_nm; /* the gauge's reading */
} gauge_fault_t;

/* Gauge unusable: the torque loop cannot run, DAMP (open loop) in that
 * tick; the first good sample resumes TORQUE. */
static void test_reaction_gauge_unusable(void)
{
    const gauge_fault_t cases[] = {
        {"adc_error", HAL_ERR_IO, false, 1.0},
        {"saturated", HAL_OK, true, 1.0},
        {"open_bridge", HAL_ERR_FAULT, false, 1.0},
        {"out_of_range", HAL_OK, false, 250.0}, /* beyond torque_limit_nm (200) */
    };
    for (size_t i = 0; i < sizeof cases / sizeof cases[0]; i++) {
        start(true);
        settle_torque();
        fault_smp.adc_rc = cases[i].adc_rc;
        fault_smp.adc.saturated = cases[i].saturated;
        fault_smp.adc.bridge_counts = counts_of(cases[i].torque_nm);
        uint32_t faults = 0u;
        const int react = ticks_until(HD_CTRL_DAMP, 10u, 1.0f, &faults);
        TEST_ASSERT_EQUAL_INT_MESSAGE(0, react, cases[i].name);
        TEST_ASSERT_TRUE_MESSAGE(drv.enabled, cases[i].name); /* DAMP drives */
        TEST_ASSERT_TRUE_MESSAGE(faults & HD_FAULT_CTRL_FALLBACK, cases[i].name);
        for (int n = 0; n < 100; n++) { /* DAMP while it lasts */
            sample_tick(1.0f, 1u);
            TEST_ASSERT_EQUAL_INT_MESSAGE(HD_CTRL_DAMP, mode_run(), cases[i].name);
        }
        healthy_sample(counts_of(1.0));
        uint32_t ignored = 0u;
        const int resume = ticks_until(HD_CTRL_TORQUE, 10u, 1.0f, &ignored);
        TEST_ASSERT_EQUAL_INT_MESSAGE(0, resume, cases[i].name);
        printf("measured: ctrl_gauge_%s reaction_ticks=%d limit_ticks=0 faults=%x "
               "resume_ticks=%d\n", cases[i].name, react, faults, resume);
    }
}

/* The gauge: 5 N m and a 2 N m line at twice the motor angle. */
static int32_t ripple_counts(void)
{
    const double theta = 2.0 * TEST_PI * (double)(motor % CPR) / (double)CPR;
    return counts_of(5.0 + 2.0 * sin(2.0 * theta));
}

/* A real restart: the filter's correction held at a tiny correction_max_nm
 * for HD_KF_LIMIT_RESTART_S restarts it (KF_RESET).  The restarted filter
 * has no estimate yet: DAMP for that tick, TORQUE again after it. */
static void test_reaction_filter_reset(void)
{
    start(true);
    cfg.filter_enabled = 1u;
    cfg.kf.correction_max_nm = 0.01f;
    init_fw();
    int reset_at = -1, react = -1, resume = -1;
    uint32_t faults = 0u;
    for (int n = 0; n < 3000 && resume < 0; n++) {
        fault_smp.adc.bridge_counts = ripple_counts();
        sample_tick(5.0f, 20u);
        if (reset_at < 0 && (fw.last.faults & HD_FAULT_KF_RESET) != 0u) {
            reset_at = n;
        }
        if (reset_at >= 0) {
            faults |= fw.last.faults;
            if (react < 0 && mode_run() == HD_CTRL_DAMP) {
                react = n - reset_at;
            } else if (react >= 0 && mode_run() == HD_CTRL_TORQUE) {
                resume = n - reset_at - react;
            }
        } else {
            TEST_ASSERT_EQUAL_INT(HD_CTRL_TORQUE, mode_run());
        }
    }
    TEST_ASSERT_TRUE(reset_at > 0);
    TEST_ASSERT_EQUAL_INT(0, react);
    TEST_ASSERT_EQUAL_INT(1, resume);
    TEST_ASSERT_TRUE(faults & HD_FAULT_CTRL_FALLBACK);
    printf("measured: ctrl_filter_reset reaction_ticks=%d limit_ticks=0 faults=%x "
           "resume_ticks=%d at_tick=%d\n", react, faults, resume, reset_at);
}

/* Frozen (a block over Nyquist): no reaction, by design; the frozen block
 * holds its estimate and the torque loop keeps running. */
static void test_reaction_filter_frozen(void)
{
    start(true);
    cfg.filter_enabled = 1u;
    init_fw();
    healthy_sample(counts_of(1.0));
    const uint32_t step = 590u; /* 905 rad/s: motor order 4 at 576 Hz */
    unsigned frozen = 0u, other_mode = 0u;
    uint32_t faults = 0u;
    for (int n = 0; n < 500; n++) {
        sample_tick(1.0f, step);
        faults |= fw.last.faults;
        frozen += (fw.last.faults & HD_FAULT_KF_FROZEN) != 0u;
        other_mode += n > 0 && mode_run() != HD_CTRL_TORQUE;
    }
    TEST_ASSERT_TRUE(frozen > 400u);
    TEST_ASSERT_EQUAL_UINT(0u, other_mode);
    TEST_ASSERT_TRUE(drv.enabled);
    printf("measured: ctrl_filter_frozen frozen_ticks=%u other_mode_ticks=%u faults=%x "
           "speed_rad_s=%.0f\n", frozen, other_mode, faults,
           (double)step * 2.0 * TEST_PI / CPR * 1000.0);
}

static void test_reaction_drive(void)
{
    /* the drive reports a fault */
    start(true);
    settle_torque();
    drv.fault = true;
    uint32_t faults = 0u;
    const int react = ticks_until(HD_CTRL_STOP, 10u, 1.0f, &faults);
    TEST_ASSERT_EQUAL_INT(0, react);
    TEST_ASSERT_TRUE(faults & HD_FAULT_DRIVE_FAULT);
    TEST_ASSERT_FALSE(drv.enabled);
    drv.fault = false;
    sample_tick(1.0f, 1u);
    TEST_ASSERT_EQUAL_INT(HD_CTRL_STOP, mode_run()); /* latched */
    const int resume = release_latched_stop();
    TEST_ASSERT_EQUAL_INT(1, resume);
    printf("measured: ctrl_drive_fault reaction_ticks=%d limit_ticks=0 faults=%x resume_ticks=%d\n",
           react, faults, resume);

    /* a drive call fails: disabled in that tick, STOP latched */
    settle_torque();
    drv.command_rc = HAL_ERR_IO;
    faults = 0u;
    const uint32_t commands = drv.commands;
    const int react2 = ticks_until(HD_CTRL_STOP, 10u, 1.0f, &faults);
    TEST_ASSERT_EQUAL_INT(0, react2);
    TEST_ASSERT_EQUAL_UINT32(commands + 1u, drv.commands); /* the failed one only */
    sample_tick(1.0f, 1u);
    TEST_ASSERT_EQUAL_INT(HD_CTRL_STOP, mode_run());
    TEST_ASSERT_TRUE(faults & HD_FAULT_DRIVE_FAULT);
    TEST_ASSERT_FALSE(drv.enabled);
    drv.command_rc = HAL_OK;
    const int resume2 = release_latched_stop();
    TEST_ASSERT_EQUAL_INT(1, resume2);
    printf("measured: ctrl_drive_call_failed reaction_ticks=%d limit_ticks=0 faults=%x "
           "resume_ticks=%d\n", react2, faults, resume2);
}

static void test_reaction_bus_off(void)
{
    start(true);
    settle_torque();
    mock.bus_off = true;
    uint32_t faults = 0u;
    /* the tick's telemetry fails after its control stage: seen by the next */
    const int react = ticks_until(HD_CTRL_DAMP, 20u, 1.0f, &faults);
    TEST_ASSERT_TRUE(react >= 0 && react <= 1);
    for (int n = 0; n < 100; n++) {
        sample_tick(1.0f, 1u);
        TEST_ASSERT_EQUAL_INT(HD_CTRL_DAMP, mode_run());
    }
    mock.bus_off = false;
    /* DAMP holds until a send period (telemetry at 100 Hz here) passes clean */
    const uint32_t period = 1000u / live_cfg()->telemetry_rate_hz;
    uint32_t ignored = 0u;
    const int resume = ticks_until(HD_CTRL_TORQUE, 20u, 1.0f, &ignored);
    TEST_ASSERT_TRUE(resume >= 0 && resume <= (int)period);
    TEST_ASSERT_TRUE(faults & HD_FAULT_CAN_BUS_OFF);
    printf("measured: ctrl_bus_off reaction_ticks=%d limit_ticks=1 faults=%x resume_ticks=%d "
           "send_period_ticks=%u\n", react, faults, resume, (unsigned)period);
}

/* Repeated deadline misses: one alone does nothing; a third within the
 * score's memory is DAMP in the tick that sees it. */
static void test_reaction_deadline_misses(void)
{
    start(true);
    settle_torque();
    hd_fw_note_deadline_miss(&fw, 1u);
    for (int n = 0; n < 40; n++) {
        sample_tick(1.0f, 1u);
        TEST_ASSERT_EQUAL_INT(HD_CTRL_TORQUE, mode_run());
    }
    uint32_t faults = 0u;
    int misses = 0, react = -1;
    while (misses < 10 && react < 0) {
        hd_fw_note_deadline_miss(&fw, 1u);
        misses++;
        sample_tick(1.0f, 1u);
        faults |= fw.last.faults;
        react = mode_run() == HD_CTRL_DAMP ? 0 : -1;
    }
    TEST_ASSERT_EQUAL_INT(0, react);
    TEST_ASSERT_EQUAL_INT(3, misses);
    uint32_t ignored = 0u;
    const int resume = ticks_until(HD_CTRL_TORQUE, 100u, 1.0f, &ignored);
    TEST_ASSERT_TRUE(resume > 0 && resume < 50);
    printf("measured: ctrl_deadline_misses reaction_ticks=%d limit_ticks=0 faults=%x misses=%d "
           "resume_ticks=%d\n", react, faults, misses, resume);
}

/* Whatever arrives (random SETPOINT / GAINS payloads and lengths, the gauge
 * anywhere in its range or failing, the motor at any speed, deadline
 * misses), no command exceeds ctrl_current_limit_a or is not finite. */
static uint32_t lcg_state = 12345u;

static uint32_t lcg(void)
{
    lcg_state = lcg_state * 1664525u + 1013904223u;
    return lcg_state >> 8;
}

/* uniform in [lo, hi) */
static float uniform(float lo, float hi)
{
    return lo + (hi - lo) * (float)(lcg() % 65536u) / 65536.0f;
}

/* A random SETPOINT or GAINS frame: raw bytes and lengths, or encoded
 * values in and beyond their ranges (any mode, some unknown). */
static void random_control_frame(uint8_t node, hal_can_frame_t *f)
{
    const float lim = live_cfg()->ctrl.torque_limit_nm;
    memset(f, 0, sizeof *f);
    switch (lcg() % 4u) {
    case 0:
    case 1:
        f->id = id_of((lcg() & 1u) != 0u ? HD_CAN_FRAME_GAINS : HD_CAN_FRAME_SETPOINT, node);
        f->len = (lcg() & 1u) != 0u ? 8u : (uint8_t)(lcg() % 9u);
        for (unsigned b = 0; b < 8u; b++) {
            f->data[b] = (uint8_t)lcg();
        }
        break;
    case 2: {
        const hd_can_setpoint_t sp = {(uint8_t)(lcg() % (HD_CTRL_MODE_COUNT + 2u)), (uint8_t)lcg(),
                                      uniform(-1.2f * lim, 1.2f * lim), uniform(-2.0f, 2.0f),
                                      uniform(-50.0f, 50.0f)};
        hd_can_encode_setpoint(node, &sp, f);
        break;
    }
    default: {
        const hd_can_gains_t g = {uniform(-1.0f, 1.2f * HD_CTRL_KP_MAX_NM_RAD),
                                  uniform(-1.0f, 1.2f * HD_CTRL_KD_MAX_NM_S_RAD)};
        hd_can_encode_gains(node, &g, f);
        break;
    }
    }
}

static void test_no_command_beyond_the_limit_whatever_the_input(void)
{
    start(true);
    const uint8_t node = live_cfg()->node_id;
    const unsigned ticks = 20000u;
    unsigned frames = 0u;
    uint32_t seen_modes = 0u;
    for (unsigned n = 0; n < ticks; n++) {
        if ((lcg() & 3u) != 0u) {
            hal_can_frame_t f;
            random_control_frame(node, &f);
            hal_mock_push_rx(&mock, &f);
            frames++;
        }
        memset(&fault_smp, 0, sizeof fault_smp);
        const uint32_t g = lcg();
        fault_smp.adc.bridge_counts = (int32_t)(g % 65536u) - 32768;
        const uint32_t which = lcg() % 512u; /* a sensor fault now and then */
        fault_smp.adc.saturated = which == 0u;
        fault_smp.adc_rc = which == 1u ? HAL_ERR_IO : which == 2u ? HAL_ERR_FAULT : HAL_OK;
        fault_smp.enc.fault = which == 3u;
        if (which == 4u) {
            hd_fw_note_deadline_miss(&fw, 1u + lcg() % 3u);
        }
        motor += lcg() % 600u;
        hal_mock_sample_t smp = fault_smp;
        smp.enc.motor_counts = motor;
        hal_mock_push_sample(&mock, &smp);
        hd_fw_isr(&fw);
        hd_fw_background(&fw);
        seen_modes |= 1u << mode_run();
        if (!fw.control.out.enable) {
            TEST_ASSERT_FALSE(drv.enabled);
        }
    }
    const float limit = live_cfg()->ctrl.current_limit_a;
    printf("measured: ctrl_any_input ticks=%u frames=%u max_abs_a=%.4f limit_a=%.4f "
           "non_finite=%u modes=%x\n", ticks, frames, (double)drv.max_abs_a, (double)limit,
           drv.non_finite, seen_modes);
    TEST_ASSERT_EQUAL_UINT(0u, drv.non_finite);
    TEST_ASSERT_TRUE(drv.max_abs_a <= limit);
    /* it did drive, in every mode */
    TEST_ASSERT_EQUAL_HEX32((1u << HD_CTRL_MODE_COUNT) - 1u, seen_modes);
    TEST_ASSERT_TRUE(drv.max_abs_a > 0.5f * limit);
}

static void test_no_drive_sends_nothing_new(void)
{
    start(false);
    const uint32_t from = hal_mock_tx_count(&mock);
    setpoint_tick(HD_CTRL_TORQUE, 1.0f);
    run(20, counts_of(0.0), 1);
    TEST_ASSERT_EQUAL_INT(HD_CAN_RES_UNSUPPORTED, refusal_since(from).result);
    TEST_ASSERT_EQUAL_UINT32(0u, count_id(id_of(HD_CAN_FRAME_CTRL_STATE, live_cfg()->node_id)));
    /* STOP is accepted (nothing to do) */
    const uint32_t refused = fw.counters.by_fault[HD_FAULT_BIT_SETPOINT_REFUSED];
    setpoint_tick(HD_CTRL_STOP, 0.0f);
    TEST_ASSERT_EQUAL_UINT32(refused, fw.counters.by_fault[HD_FAULT_BIT_SETPOINT_REFUSED]);
}

/* A setting outside the law (the telemetry rate) swaps the settings but
 * keeps the loop's state: its integrator runs on; one of the law's own
 * (ctrl_torque_ki_per_s) restarts it from zero.  The restart is the costly
 * part of a settings swap in the tick (tools/target budget). */
static void test_settings_swap_restarts_the_law_only_when_its_own_change(void)
{
    start(true);
    for (int k = 0; k < 50; k++) {
        setpoint_tick(HD_CTRL_TORQUE, 2.0f);
    }
    const float integral = fw.control.ctrl.integral_nm;
    TEST_ASSERT_TRUE(fabsf(integral) > 1e-3f); /* the loop integrates the error */
    TEST_ASSERT_EQUAL_UINT8(HD_CAN_RES_OK, set_param(HD_PARAM_TELEMETRY_RATE_HZ, 50.0f).result);
    setpoint_tick(HD_CTRL_TORQUE, 2.0f);
    TEST_ASSERT_EQUAL_UINT32(50u, live_cfg()->telemetry_rate_hz); /* swapped */
    TEST_ASSERT_TRUE(fabsf(fw.control.ctrl.integral_nm) >= 0.5f * fabsf(integral));
    TEST_ASSERT_EQUAL_UINT8(HD_CAN_RES_OK,
                            set_param(HD_PARAM_CTRL_TORQUE_KI_PER_S,
                                      0.5f * live_cfg()->ctrl.torque_ki_per_s).result);
    setpoint_tick(HD_CTRL_TORQUE, 2.0f);
    TEST_ASSERT_EQUAL_FLOAT(0.5f * fw.bg.defaults.ctrl.torque_ki_per_s,
                            fw.control.ctrl.plan->cfg.torque_ki_per_s);
    TEST_ASSERT_TRUE(fabsf(fw.control.ctrl.integral_nm) < 0.2f * fabsf(integral));
}

/* A filter block switched off and on moves the law to the new settings'
 * motor orders (the narrowed feedback's artifact mask) without a restart:
 * the integral runs on, the law's plan is the live settings'. */
static void test_block_switch_moves_the_orders_without_a_restart(void)
{
    start(true);
    for (int k = 0; k < 50; k++) {
        setpoint_tick(HD_CTRL_TORQUE, 2.0f);
    }
    const float integral = fw.control.ctrl.integral_nm;
    const uint8_t mask = fw.control.ctrl.artifact.mask;
    TEST_ASSERT_TRUE(fabsf(integral) > 1e-3f);
    TEST_ASSERT_TRUE(mask != 0u); /* the default model has motor-locked blocks */
    hd_can_cmd_t e = {0};
    e.opcode = HD_CMD_BLOCK_ENABLE;
    for (uint8_t b = 0; b < live_cfg()->kf.block_count; b++) {
        e.arg.block_enable.index = b;
        TEST_ASSERT_EQUAL_UINT8(HD_CAN_RES_OK, send_cmd(&e).result);
    }
    setpoint_tick(HD_CTRL_TORQUE, 2.0f);
    TEST_ASSERT_EQUAL_UINT8(0u, fw.control.ctrl.artifact.mask);
    TEST_ASSERT_TRUE(fw.control.ctrl.plan == &fw.settings[fw.live_settings & 1u].ctrl);
    TEST_ASSERT_TRUE(fabsf(fw.control.ctrl.integral_nm) >= 0.5f * fabsf(integral));
    e.arg.block_enable.enable = 1u;
    for (uint8_t b = 0; b < live_cfg()->kf.block_count; b++) {
        e.arg.block_enable.index = b;
        TEST_ASSERT_EQUAL_UINT8(HD_CAN_RES_OK, send_cmd(&e).result);
    }
    setpoint_tick(HD_CTRL_TORQUE, 2.0f);
    TEST_ASSERT_EQUAL_UINT8(mask, fw.control.ctrl.artifact.mask);
    TEST_ASSERT_TRUE(fw.control.ctrl.plan == &fw.settings[fw.live_settings & 1u].ctrl);
    TEST_ASSERT_TRUE(fabsf(fw.control.ctrl.integral_nm) >= 0.5f * fabsf(integral));
}

static void test_ctrl_state_telemetry(void)
{
    start(true);
    for (int i = 0; i < 12; i++) {
        setpoint_tick(HD_CTRL_TORQUE, 3.0f);
    }
    const hal_can_frame_t *f = last_id(id_of(HD_CAN_FRAME_CTRL_STATE, live_cfg()->node_id));
    TEST_ASSERT_NOT_NULL(f);
    hd_can_ctrl_state_t st;
    TEST_ASSERT_EQUAL_INT(0, hd_can_decode_ctrl_state(f, &st));
    TEST_ASSERT_EQUAL_UINT8(HD_CTRL_TORQUE, st.mode_asked);
    TEST_ASSERT_EQUAL_UINT8(HD_CTRL_TORQUE, st.mode_run);
    TEST_ASSERT_FLOAT_WITHIN(0.01f, 3.0f, st.torque_ref_nm);
    TEST_ASSERT_TRUE(st.flags & HD_CAN_CTRL_FLAG_ENABLED);
}

int main(int argc, char **argv)
{
    if (UnityParseOptions(argc, argv) != 0) {
        return 1;
    }
    UNITY_BEGIN();
    RUN_TEST(test_watchdog_damp_then_stop);
    RUN_TEST(test_fresh_setpoints_keep_the_mode);
    RUN_TEST(test_bad_setpoints_refused_never_reach_the_drive);
    RUN_TEST(test_bad_gains_short_frames_and_other_nodes);
    RUN_TEST(test_current_never_beyond_its_limit);
    RUN_TEST(test_reaction_encoder_lost);
    RUN_TEST(test_reaction_gauge_unusable);
    RUN_TEST(test_reaction_filter_reset);
    RUN_TEST(test_reaction_filter_frozen);
    RUN_TEST(test_reaction_drive);
    RUN_TEST(test_reaction_bus_off);
    RUN_TEST(test_reaction_deadline_misses);
    RUN_TEST(test_no_command_beyond_the_limit_whatever_the_input);
    RUN_TEST(test_no_drive_sends_nothing_new);
    RUN_TEST(test_block_switch_moves_the_orders_without_a_restart);
    RUN_TEST(test_ctrl_state_telemetry);
    RUN_TEST(test_settings_swap_restarts_the_law_only_when_its_own_change);
    return UNITY_END();
}
