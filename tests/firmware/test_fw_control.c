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
 *   - no command ever exceeds ctrl_current_limit_a;
 *   - each fault reaction: encoder lost -> STOP latched until a STOP
 *     setpoint; gauge saturated -> DAMP; drive fault -> STOP; bus-off and
 *     repeated deadline misses -> DAMP; each within the tick it is seen;
 *   - a board without a drive sends nothing new and refuses control modes.
 */
#include <math.h>
#include <stdio.h>

#include "fw_rig.h"

void setUp(void) {}
void tearDown(void) {}

/* ------------------------------------------------------ recording drive */

typedef struct {
    bool enabled;
    bool fault;           /* reported by status */
    int command_rc;       /* returned by command_current */
    uint32_t enables;     /* enable(true) calls */
    uint32_t commands;
    float last_a;
    float max_abs_a;
} rec_drive_t;

static rec_drive_t drv;

static int rd_enable(void *ctx, bool on)
{
    rec_drive_t *d = ctx;
    d->enabled = on;
    d->enables += on ? 1u : 0u;
    return HAL_OK;
}

static int rd_command(void *ctx, float a)
{
    rec_drive_t *d = ctx;
    d->commands++;
    d->last_a = a;
    d->max_abs_a = fmaxf(d->max_abs_a, fabsf(a));
    return d->command_rc;
}

static int rd_status(void *ctx, hal_drive_status_t *out)
{
    const rec_drive_t *d = ctx;
    *out = (hal_drive_status_t){.enabled = d->enabled, .fault = d->fault, .bus_voltage_v = NAN,
                                .temperature_c = NAN, .current_a = NAN};
    return HAL_OK;
}

/* counts for a gauge torque of tau (calibration GAIN, OFFSET_V of the rig) */
static int32_t counts_of(double tau_nm)
{
    return (int32_t)lround((tau_nm / GAIN + OFFSET_V) / VPC);
}

static void start(bool with_drive)
{
    rig_reset();
    cfg.telemetry_rate_hz = 100u; /* the mock's transmit log holds 512 frames */
    cfg.ctrl.position_min_rad = -1.0f;
    cfg.ctrl.position_max_rad = 1.0f;
    memset(&drv, 0, sizeof drv);
    if (with_drive) {
        hal.actuator = (hal_actuator_t){&drv, rd_enable, rd_command, rd_status};
    }
    init_fw();
}

static uint8_t seq_next = 1u;

static void push_setpoint(uint8_t mode, float torque_nm, float position_rad, uint8_t seq)
{
    const hd_can_setpoint_t sp = {mode, seq, torque_nm, position_rad, 0.0f};
    hal_can_frame_t f;
    hd_can_encode_setpoint(live_cfg()->node_id, &sp, &f);
    TEST_ASSERT_EQUAL_INT(0, hal_mock_push_rx(&mock, &f));
}

/* One tick with a new setpoint. */
static void setpoint_tick(uint8_t mode, float torque_nm)
{
    push_setpoint(mode, torque_nm, 0.0f, seq_next++);
    run(1, counts_of(0.0), 1);
}

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
    for (unsigned n = 1; n <= timeout + damp + 5u; n++) {
        /* the same sequence number again: stale, it does not feed the watchdog */
        push_setpoint(HD_CTRL_TORQUE, 2.0f, 0.0f, (uint8_t)(seq_next - 1u));
        run(1, counts_of(0.0), 1);
        fault_seen |= (fw.last.faults & HD_FAULT_CTRL_WATCHDOG) != 0u;
        if (damp_at < 0 && mode_run() == HD_CTRL_DAMP) {
            damp_at = (int)(fw.counters.ticks - t0);
        }
        if (stop_at < 0 && mode_run() == HD_CTRL_STOP) {
            stop_at = (int)(fw.counters.ticks - t0);
        }
    }
    printf("fw_control: watchdog %u ms: DAMP %d ticks after the last setpoint, STOP %d ticks\n",
           timeout, damp_at, stop_at);
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
    }
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
    printf("fw_control: largest command %.4f A, limit %.4f A\n", (double)drv.max_abs_a,
           (double)live_cfg()->ctrl.current_limit_a);
    TEST_ASSERT_FLOAT_WITHIN(1e-6, live_cfg()->ctrl.current_limit_a, drv.max_abs_a);
    TEST_ASSERT_TRUE(fw.control.out.limits & HD_CTRL_LIM_CURRENT);
}

static void test_fault_reactions(void)
{
    /* encoder lost: STOP in that tick, latched until a STOP setpoint */
    start(true);
    setpoint_tick(HD_CTRL_TORQUE, 1.0f);
    hal_mock_sample_t smp = {0};
    smp.adc.bridge_counts = counts_of(0.0);
    smp.enc.motor_counts = motor;
    smp.enc.fault = true;
    push_setpoint(HD_CTRL_TORQUE, 1.0f, 0.0f, seq_next++);
    hal_mock_push_sample(&mock, &smp);
    hd_fw_isr(&fw);
    hd_fw_background(&fw);
    TEST_ASSERT_EQUAL_INT(HD_CTRL_STOP, mode_run());
    TEST_ASSERT_FALSE(drv.enabled);
    TEST_ASSERT_TRUE(fw.last.faults & HD_FAULT_CTRL_FALLBACK);
    setpoint_tick(HD_CTRL_TORQUE, 1.0f); /* encoder back: still latched */
    TEST_ASSERT_EQUAL_INT(HD_CTRL_STOP, mode_run());
    setpoint_tick(HD_CTRL_STOP, 0.0f);
    setpoint_tick(HD_CTRL_TORQUE, 1.0f);
    TEST_ASSERT_EQUAL_INT(HD_CTRL_TORQUE, mode_run());

    /* gauge saturated: the torque loop cannot run, DAMP in that tick */
    smp.enc.fault = false;
    smp.enc.motor_counts = ++motor;
    smp.adc.saturated = true;
    push_setpoint(HD_CTRL_TORQUE, 1.0f, 0.0f, seq_next++);
    hal_mock_push_sample(&mock, &smp);
    hd_fw_isr(&fw);
    TEST_ASSERT_EQUAL_INT(HD_CTRL_DAMP, mode_run());
    TEST_ASSERT_TRUE(drv.enabled);

    /* drive fault: STOP, DRIVE_FAULT */
    setpoint_tick(HD_CTRL_TORQUE, 1.0f);
    TEST_ASSERT_EQUAL_INT(HD_CTRL_TORQUE, mode_run());
    drv.fault = true;
    setpoint_tick(HD_CTRL_TORQUE, 1.0f);
    TEST_ASSERT_EQUAL_INT(HD_CTRL_STOP, mode_run());
    TEST_ASSERT_TRUE(fw.last.faults & HD_FAULT_DRIVE_FAULT);
    TEST_ASSERT_FALSE(drv.enabled);
    drv.fault = false;
    setpoint_tick(HD_CTRL_STOP, 0.0f);

    /* a failed drive call: STOP, DRIVE_FAULT */
    setpoint_tick(HD_CTRL_TORQUE, 1.0f);
    drv.command_rc = HAL_ERR_IO;
    setpoint_tick(HD_CTRL_TORQUE, 1.0f);
    TEST_ASSERT_TRUE(fw.last.faults & HD_FAULT_DRIVE_FAULT);
    TEST_ASSERT_FALSE(drv.enabled);
    drv.command_rc = HAL_OK;
    setpoint_tick(HD_CTRL_STOP, 0.0f);

    /* repeated deadline misses: DAMP; one alone does not */
    setpoint_tick(HD_CTRL_TORQUE, 1.0f);
    hd_fw_note_deadline_miss(&fw, 1u);
    setpoint_tick(HD_CTRL_TORQUE, 1.0f);
    TEST_ASSERT_EQUAL_INT(HD_CTRL_TORQUE, mode_run());
    for (int i = 0; i < 2; i++) {
        hd_fw_note_deadline_miss(&fw, 1u);
        setpoint_tick(HD_CTRL_TORQUE, 1.0f);
    }
    TEST_ASSERT_EQUAL_INT(HD_CTRL_DAMP, mode_run());
    for (int i = 0; i < 40; i++) {
        setpoint_tick(HD_CTRL_TORQUE, 1.0f);
    }
    TEST_ASSERT_EQUAL_INT(HD_CTRL_TORQUE, mode_run());

    /* bus-off: DAMP while it lasts */
    mock.bus_off = true;
    setpoint_tick(HD_CTRL_TORQUE, 1.0f); /* the telemetry of this tick fails: seen next tick */
    for (int i = 0; i < 20 && mode_run() != HD_CTRL_DAMP; i++) {
        setpoint_tick(HD_CTRL_TORQUE, 1.0f);
    }
    TEST_ASSERT_EQUAL_INT(HD_CTRL_DAMP, mode_run());
    mock.bus_off = false;
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
    RUN_TEST(test_fault_reactions);
    RUN_TEST(test_no_drive_sends_nothing_new);
    RUN_TEST(test_ctrl_state_telemetry);
    return UNITY_END();
}
