/*
 * The identification run (firmware/hd_fw_ident.c, IDENT_START) on the mock
 * HAL with a recording drive:
 *   - tick k of a run tells the drive the law's current plus the waveform's
 *     sample k (control/hd_excite, tested against its closed form in
 *     control_excite), and sends one IDENT frame whose fields say so, the
 *     run's tick and its status; the run ends by itself after (periods + 1)
 *     periods and the drive gets the law's current alone again;
 *   - a mode the run cannot excite (a DAMP setpoint, the watchdog) ends it
 *     in that tick, said in its frame;
 *   - the sum never crosses ctrl_current_limit_a: the drive is told the
 *     limit and the run ends (status 3);
 *   - refused with a status: no drive, periods 0 or beyond the range, an
 *     rms below its range, not finite, or whose peak exceeds half the
 *     current limit, a start during a run (which goes on).
 */
#include <stdio.h>

#include "fw_drive_rig.h"

void setUp(void) {}
void tearDown(void) {}

#define TORQUE_NM 2.0f

static hd_can_ack_t ident_start(uint8_t periods, float rms_a)
{
    hd_can_cmd_t c = {0};
    c.opcode = HD_CMD_IDENT_START;
    c.token = 0x44;
    c.arg.ident_start.periods = periods;
    c.arg.ident_start.rms_a = rms_a;
    return send_cmd(&c);
}

/* The IDENT frames sent since the last call (the transmit log is cleared). */
static unsigned take_ident(hd_can_ident_t *out, unsigned cap)
{
    unsigned n = 0;
    const uint32_t id = id_of(HD_CAN_FRAME_IDENT, live_cfg()->node_id);
    for (uint32_t i = 0; i < hal_mock_tx_count(&mock); i++) {
        const hal_can_frame_t *f = hal_mock_tx(&mock, i);
        if (f->id == id) {
            TEST_ASSERT_TRUE(n < cap);
            TEST_ASSERT_EQUAL_INT(0, hd_can_decode_ident(f, &out[n++]));
        }
    }
    hal_mock_tx_clear(&mock);
    return n;
}

/* A joint in TORQUE at TORQUE_NM (the gauge reads 0: the law's current is
 * its feed-forward plus a wound-up integral) with a run of one period
 * started; *first holds the run's frames sent with the command's ACK. */
static unsigned start_run(float rms_a, hd_can_ident_t *first, unsigned cap)
{
    for (int i = 0; i < 50; i++) {
        setpoint_tick(HD_CTRL_TORQUE, TORQUE_NM);
    }
    hal_mock_tx_clear(&mock);
    const hd_can_ack_t a = ident_start(1u, rms_a);
    TEST_ASSERT_EQUAL_INT(HD_CAN_RES_OK, a.result);
    TEST_ASSERT_EQUAL_UINT8(1u, a.aux);
    TEST_ASSERT_FLOAT_WITHIN(1e-6f, fw.ident.excite.peak_a, a.value);
    return take_ident(first, cap);
}

static void test_a_run_adds_the_waveform_and_reports_every_tick(void)
{
    start(true);
    hd_can_ident_t fr[4];
    unsigned got = start_run(0.4f, fr, 4);
    TEST_ASSERT_TRUE(got >= 1u);
    TEST_ASSERT_FLOAT_WITHIN(1e-3f, 1.669f, fw.ident.excite.peak_a);
    const uint32_t total = 2u * HD_EXCITE_PERIOD_TICKS;
    uint32_t k = 0;
    float worst_a = 0.0f;
    for (uint32_t t = 0; t < total + 20u; t++) {
        for (unsigned i = 0; i < got; i++, k++) {
            const hd_can_ident_t *x = &fr[i];
            TEST_ASSERT_EQUAL_UINT8((uint8_t)k, x->tick);
            TEST_ASSERT_EQUAL_UINT8(k + 1u == total ? HD_FW_IDENT_DONE : HD_FW_IDENT_RUNNING,
                                    x->status);
            /* what the drive got minus the law's, to the frame's 1 mA */
            const float excite_a = hd_excite_at(&fw.ident.excite, k);
            worst_a = fmaxf(worst_a, fabsf(x->drive_a - x->cmd_a - excite_a));
        }
        if (k > 0u && k < total) {   /* this tick's frame: the drive got drive_a */
            TEST_ASSERT_FLOAT_WITHIN(6e-4f, drv.last_a, fr[got - 1u].drive_a);
            TEST_ASSERT_FLOAT_WITHIN(6e-4f, fw.control.out.current_a, fr[got - 1u].cmd_a);
        }
        setpoint_tick(HD_CTRL_TORQUE, TORQUE_NM);
        got = take_ident(fr, 4);
        TEST_ASSERT_TRUE(got <= 1u);
        if (k >= total) {
            TEST_ASSERT_EQUAL_UINT(0u, got);
            TEST_ASSERT_EQUAL_FLOAT(fw.control.out.current_a, drv.last_a); /* the law's alone */
        }
    }
    printf("ident: %u frames, worst |drive - cmd - excitation| %.2e A\n", (unsigned)total,
           (double)worst_a);
    TEST_ASSERT_TRUE(worst_a <= 1.1e-3f);
    TEST_ASSERT_FALSE(fw.ident.running);
}

static void test_a_mode_it_cannot_excite_ends_the_run(void)
{
    start(true);
    hd_can_ident_t fr[4];
    (void)start_run(0.4f, fr, 4);
    for (int i = 0; i < 100; i++) {
        setpoint_tick(HD_CTRL_TORQUE, TORQUE_NM);
        TEST_ASSERT_EQUAL_UINT(1u, take_ident(fr, 4));
    }
    setpoint_tick(HD_CTRL_DAMP, 0.0f);
    TEST_ASSERT_EQUAL_UINT(1u, take_ident(fr, 4));
    TEST_ASSERT_EQUAL_UINT8(HD_FW_IDENT_MODE, fr[0].status);
    TEST_ASSERT_EQUAL_FLOAT(fr[0].cmd_a, fr[0].drive_a);
    setpoint_tick(HD_CTRL_TORQUE, TORQUE_NM);
    TEST_ASSERT_EQUAL_UINT(0u, take_ident(fr, 4));
    TEST_ASSERT_EQUAL_FLOAT(fw.control.out.current_a, drv.last_a);

    /* the watchdog: DAMP once the setpoints stop */
    (void)start_run(0.4f, fr, 4);
    unsigned ticks = 0;
    uint8_t status = HD_FW_IDENT_RUNNING;
    while (status == HD_FW_IDENT_RUNNING && ticks < 1000u) {
        run(1, counts_of(0.0), 1);
        ticks++;
        for (unsigned i = 0, n = take_ident(fr, 4); i < n; i++) {
            status = fr[i].status;
        }
    }
    TEST_ASSERT_EQUAL_UINT8(HD_FW_IDENT_MODE, status);
    TEST_ASSERT_EQUAL_INT(HD_CTRL_DAMP, fw.control.out.mode);
    TEST_ASSERT_TRUE(ticks <= live_cfg()->ctrl_watchdog_ms + 1u);
}

static void test_the_sum_never_crosses_the_current_limit(void)
{
    rig_reset();
    start(true);
    TEST_ASSERT_EQUAL_INT(HD_CAN_RES_OK, set_param(HD_PARAM_CTRL_CURRENT_LIMIT_A, 4.0f).result);
    hd_can_ident_t fr[4];
    /* 30 N m with no torque measured: the law saturates at the limit */
    for (int i = 0; i < 200; i++) {
        setpoint_tick(HD_CTRL_TORQUE, 30.0f);
    }
    TEST_ASSERT_FLOAT_WITHIN(1e-6f, 4.0f, fw.control.out.current_a);
    hal_mock_tx_clear(&mock);
    TEST_ASSERT_EQUAL_INT(HD_CAN_RES_OK, ident_start(3u, 0.4f).result);
    uint8_t status = HD_FW_IDENT_RUNNING;
    for (int i = 0; i < 100 && status == HD_FW_IDENT_RUNNING; i++) {
        for (unsigned j = 0, n = take_ident(fr, 4); j < n; j++) {
            status = fr[j].status;
            TEST_ASSERT_TRUE(fabsf(fr[j].drive_a) <= 4.0f);
        }
        setpoint_tick(HD_CTRL_TORQUE, 30.0f);
    }
    TEST_ASSERT_EQUAL_UINT8(HD_FW_IDENT_LIMIT, status);
    TEST_ASSERT_TRUE(drv.max_abs_a <= 4.0f);
    TEST_ASSERT_FALSE(fw.ident.running);
}

static void test_bad_starts_are_refused(void)
{
    start(false);
    TEST_ASSERT_EQUAL_INT(HD_CAN_RES_UNSUPPORTED, ident_start(1u, 0.4f).result);
    start(true);
    TEST_ASSERT_EQUAL_INT(HD_CAN_RES_OUT_OF_RANGE, ident_start(0u, 0.4f).result);
    TEST_ASSERT_EQUAL_INT(HD_CAN_RES_OUT_OF_RANGE,
                          ident_start(HD_FW_IDENT_PERIODS_MAX + 1u, 0.4f).result);
    TEST_ASSERT_EQUAL_INT(HD_CAN_RES_OUT_OF_RANGE, ident_start(1u, 0.0005f).result);
    TEST_ASSERT_EQUAL_INT(HD_CAN_RES_NOT_FINITE, ident_start(1u, NAN).result);
    /* peak 4.17 rms: beyond half the limit at rms limit / 8 */
    const float limit = live_cfg()->ctrl.current_limit_a;
    const hd_can_ack_t big = ident_start(1u, limit / 8.0f);
    TEST_ASSERT_EQUAL_INT(HD_CAN_RES_OUT_OF_RANGE, big.result);
    TEST_ASSERT_TRUE(big.value > 0.5f * limit);
    TEST_ASSERT_FALSE(fw.ident.running);
    hd_can_ident_t fr[4];
    (void)start_run(0.4f, fr, 4);
    TEST_ASSERT_EQUAL_INT(HD_CAN_RES_BUSY, ident_start(1u, 0.4f).result);
    TEST_ASSERT_TRUE(fw.ident.running);
}

int main(void)
{
    UNITY_BEGIN();
    RUN_TEST(test_a_run_adds_the_waveform_and_reports_every_tick);
    RUN_TEST(test_a_mode_it_cannot_excite_ends_the_run);
    RUN_TEST(test_the_sum_never_crosses_the_current_limit);
    RUN_TEST(test_bad_starts_are_refused);
    return UNITY_END();
}
