/* Fault injection on the CAN side, with the simulated joint running and the
 * filter converged: transmit queue full, bus-off and recovery, error frames,
 * malformed / unknown command frames, out-of-range configuration values, a
 * flood of frames, and a calibration gain that overflows the torque to
 * infinity.
 *
 * Expectations come from docs/design/firmware.md (result codes, flags, frame
 * layout), not from running the firmware: every command is answered by one
 * ACK with the documented result code, a rejected command changes nothing
 * (configuration and calibration byte-identical), the ISR keeps one step per
 * call and the filtered torque stays within FI_BAND_NM of the truth while the
 * bus misbehaves. */
#include <math.h>
#include <string.h>

#include "fi_rig.h"
#include "rel_measured.h"
#include "unity.h"

static fi_rig_t rig;

#define T0 12000u
#define NODE_CMD_ID 0x01D01001u /* CMD of node 1 (29-bit; fi_push_cmd sets the flag) */

void setUp(void) {}
void tearDown(void) {}

static void assert_core_invariants(void)
{
    TEST_ASSERT_EQUAL_UINT32(0, rig.bad_steps);
    TEST_ASSERT_EQUAL_UINT32(0, rig.non_finite);
    TEST_ASSERT_EQUAL_UINT32(0, rig.out_of_bounds);
    TEST_ASSERT_EQUAL_UINT32(0, rig.invalid_unflagged);
    TEST_ASSERT_EQUAL_UINT32(0, rig.fw.counters.deadline_misses);
    TEST_ASSERT_EQUAL_UINT32((uint32_t)rig.tick, rig.fw.counters.ticks);
}

static void start_converged(void)
{
    fi_rig_init(&rig, "duration_s = 16\n");
    fi_rig_run(&rig, T0);
    TEST_ASSERT_TRUE(fi_max_abs_err(&rig, T0 - 1000u, T0) <= FI_BAND_NM);
}

/* Transmit side broken for 500 ticks: every frame is dropped (`bus_off`
 * false: queue full, true: bus-off). */
static void tx_outage(bool bus_off, uint16_t flag, const char *name)
{
    start_converged();
    uint32_t a_before = rig.telem_a;
    if (bus_off) {
        rig.mock.bus_off = true;
    } else {
        rig.mock.tx_budget = 0;
    }
    fi_rig_run(&rig, 500);
    TEST_ASSERT_EQUAL_UINT32(a_before, rig.telem_a); /* nothing got through */
    /* per tick: the drop is flagged on the tick after it happened */
    TEST_ASSERT_EQUAL_UINT16(flag, fi_faults_in(&rig, T0 + 1u, T0 + 500u) & flag);
    rig.mock.bus_off = false;
    rig.mock.tx_budget = -1;
    long resume = 0; /* ticks until a telemetry frame gets through again */
    while (rig.telem_a == a_before && resume < 100) {
        fi_rig_run(&rig, 1);
        resume++;
    }
    /* telemetry resumes on the first tick, carrying the flag, and the
     * sequence number shows how many periods were lost (modulo 256) */
    TEST_ASSERT_EQUAL_INT32(1, resume);
    TEST_ASSERT_EQUAL_UINT32(a_before + 1u, rig.telem_a);
    TEST_ASSERT_EQUAL_UINT16(flag, rig.telem_faults_or & flag);
    TEST_ASSERT_EQUAL_UINT32(500u % 256u, rig.seq_gaps); /* 8-bit sequence: modulo 256 */
    TEST_ASSERT_TRUE(rig.mock.counters.can_tx_dropped >= 1000u); /* 2 frames x 500 ticks */
    fi_rig_run(&rig, UINT64_MAX);
    assert_core_invariants();
    /* the heartbeat after the outage reports it too */
    TEST_ASSERT_EQUAL_UINT16(flag, rig.hb_faults_or & flag);
    TEST_ASSERT_EQUAL_UINT16(0, fi_faults_in(&rig, T0 + 502u, rig.tick) & flag);
    /* the torque path never noticed */
    double m = fi_max_abs_err(&rig, T0, rig.tick);
    char extra[48];
    snprintf(extra, sizeof extra, "window_ms=500 seq_gap=%u", (unsigned)rig.seq_gaps);
    fi_report(&rig, name, resume, 1, m, T0, T0 + 502u, extra);
    TEST_ASSERT_TRUE(m <= FI_BAND_NM);
}

static void test_tx_queue_full_500ms(void)
{
    tx_outage(false, HD_FAULT_CAN_TX_FULL, "can_tx_queue_full");
}

static void test_bus_off_500ms_and_recovery(void)
{
    tx_outage(true, HD_FAULT_CAN_BUS_OFF, "can_bus_off");
}

/* --------------------------------------------------------------- commands */

typedef struct {
    const char *what;
    uint32_t id;
    uint8_t len;
    uint8_t flags;
    uint8_t data[8];
    int result; /* expected ACK result (docs/design/firmware.md), -1: no ACK */
} bad_cmd_t;

static void put_f32(uint8_t *p, float v)
{
    uint32_t u;
    memcpy(&u, &v, 4);
    p[0] = (uint8_t)u;
    p[1] = (uint8_t)(u >> 8);
    p[2] = (uint8_t)(u >> 16);
    p[3] = (uint8_t)(u >> 24);
}

static bad_cmd_t set_param(const char *what, uint8_t id, float v, int result)
{
    bad_cmd_t c = {what, NODE_CMD_ID, 8, 0, {0x20, 0x55, id, 0, 0, 0, 0, 0}, result};
    put_f32(&c.data[4], v);
    return c;
}

static bad_cmd_t add_block(const char *what, uint8_t op, uint16_t order_x100, float q, int result)
{
    bad_cmd_t c = {what, NODE_CMD_ID, 8, 0,
                   {op, 0x66, (uint8_t)order_x100, (uint8_t)(order_x100 >> 8), 0, 0, 0, 0}, result};
    put_f32(&c.data[4], q);
    return c;
}

/* Appends result code `code` to the comma-separated list if it is new. */
static void note_code(char *list, size_t cap, uint8_t code)
{
    char item[8];
    snprintf(item, sizeof item, "%u", (unsigned)code);
    for (const char *p = list; *p != '\0';) {
        size_t len = strcspn(p, ",");
        if (len == strlen(item) && strncmp(p, item, len) == 0) {
            return;
        }
        p += len + (p[len] == ',');
    }
    size_t used = strlen(list);
    snprintf(list + used, cap - used, "%s%s", used > 0 ? "," : "", item);
}

static void run_bad_commands(const bad_cmd_t *cmds, unsigned n, const char *name)
{
    start_converged();
    /* memcpy, not assignment: the comparison below includes padding */
    hd_fw_config_t cfg_before;
    memcpy(&cfg_before, hd_fw_config(&rig.fw), sizeof cfg_before);
    uint32_t telem_before = rig.telem_a;
    uint64_t from = rig.tick;
    char codes[64] = ""; /* the distinct ACK results, in order of first use */
    for (unsigned i = 0; i < n; i++) {
        const bad_cmd_t *c = &cmds[i];
        uint32_t acks = rig.acks;
        uint32_t errors = rig.fw.counters.command_errors;
        fi_push_cmd(&rig, c->data, c->len, c->flags, c->id);
        fi_rig_run(&rig, 2); /* queued, executed, answered on the next tick */
        if (c->result < 0) {
            TEST_ASSERT_EQUAL_UINT32_MESSAGE(acks, rig.acks, c->what);
            TEST_ASSERT_EQUAL_UINT32_MESSAGE(errors, rig.fw.counters.command_errors, c->what);
        } else {
            TEST_ASSERT_EQUAL_UINT32_MESSAGE(acks + 1u, rig.acks, c->what);
            TEST_ASSERT_EQUAL_UINT8_MESSAGE(c->result, rig.last_ack[2], c->what);
            if (c->len >= 2u && (c->flags & HAL_CAN_FLAG_RTR) == 0u) {
                TEST_ASSERT_EQUAL_UINT8_MESSAGE(c->data[0], rig.last_ack[0], c->what);
                TEST_ASSERT_EQUAL_UINT8_MESSAGE(c->data[1], rig.last_ack[1], c->what);
            }
            TEST_ASSERT_EQUAL_UINT16_MESSAGE(HD_FAULT_CMD_ERROR,
                                             rig.faults[rig.tick - 1u] & HD_FAULT_CMD_ERROR,
                                             c->what);
            note_code(codes, sizeof codes, rig.last_ack[2]);
        }
        TEST_ASSERT_EQUAL_MEMORY_MESSAGE(&cfg_before, hd_fw_config(&rig.fw), sizeof cfg_before,
                                         c->what);
    }
    fi_rig_run(&rig, 500);
    assert_core_invariants();
    TEST_ASSERT_EQUAL_UINT32(telem_before + (uint32_t)(rig.tick - from), rig.telem_a);
    TEST_ASSERT_EQUAL_UINT32(0, rig.seq_gaps);
    double m = fi_max_abs_err(&rig, from, rig.tick);
    char extra[96];
    snprintf(extra, sizeof extra, "frames=%u results=%s", n, codes[0] != '\0' ? codes : "none");
    /* nothing to recover from: the filtered torque never left the band */
    fi_report(&rig, name, fi_recovery_ticks(&rig, from, FI_BAND_NM, FI_HOLD_TICKS), 0, m, from,
              rig.tick, extra);
    TEST_ASSERT_TRUE(m <= FI_BAND_NM);
}

static void test_error_frames_and_other_ids_are_ignored(void)
{
    const bad_cmd_t cmds[] = {
        {"error frame on the command id", NODE_CMD_ID, 8, HAL_CAN_FLAG_ERR, {0x20, 1, 2, 0, 0, 0, 0, 0}, -1},
        {"error frame, dlc 0", 0x20000004u, 0, HAL_CAN_FLAG_ERR, {0}, -1},
        {"command for node 2", 0x01D01002u, 8, 0, {0x01, 1, 0, 0, 0, 0, 0, 0}, -1},
        {"11-bit 0x601 (a CANopen SDO)", 0x601u, 8, 0, {0x01, 1, 0, 0, 0, 0, 0, 0}, -1},
        {"telemetry id", 0x101u, 8, 0, {0}, -1},
        {"id 0x7FF", 0x7FFu, 8, 0, {0xFF, 0xFF, 0xFF, 0xFF, 0xFF, 0xFF, 0xFF, 0xFF}, -1},
    };
    run_bad_commands(cmds, sizeof cmds / sizeof cmds[0], "can_error_frames");
    TEST_ASSERT_EQUAL_UINT32(0, rig.fw.counters.commands);
}

static void test_malformed_and_unknown_commands(void)
{
    const bad_cmd_t cmds[] = {
        {"dlc 3", NODE_CMD_ID, 3, 0, {0x01, 9, 1}, 2},
        {"dlc 0", NODE_CMD_ID, 0, 0, {0}, 2},
        {"rtr", NODE_CMD_ID, 8, HAL_CAN_FLAG_RTR, {0x01, 9, 1, 0, 0, 0, 0, 0}, 3},
        {"fd frame", NODE_CMD_ID, 8, HAL_CAN_FLAG_FD, {0x01, 9, 1, 0, 0, 0, 0, 0}, 3},
        {"unknown opcode 0x77", NODE_CMD_ID, 8, 0, {0x77, 9, 0, 0, 0, 0, 0, 0}, 1},
        {"unknown opcode 0x00", NODE_CMD_ID, 8, 0, {0x00, 9, 0, 0, 0, 0, 0, 0}, 1},
        {"unknown opcode 0xFF", NODE_CMD_ID, 8, 0, {0xFF, 9, 0, 0, 0, 0, 0, 0}, 1},
        set_param("unknown param 99", 99, 1.0f, 6),
        set_param("unknown param 0", 0, 1.0f, 6),
        set_param("read-only block count", 14, 3.0f, 7),
        {"block enable index 9", NODE_CMD_ID, 8, 0, {0x13, 3, 9, 1, 0, 0, 0, 0}, 9},
    };
    run_bad_commands(cmds, sizeof cmds / sizeof cmds[0], "can_malformed_commands");
}

static void test_out_of_range_configuration_rejected(void)
{
    const bad_cmd_t cmds[] = {
        set_param("gear ratio 0.5", 2, 0.5f, 4),
        set_param("R = 0", 1, 0.0f, 4),
        set_param("R = -1", 1, -1.0f, 4),
        set_param("R = NaN", 1, NAN, 5),
        set_param("R = +inf", 1, INFINITY, 5),
        set_param("inertia -1", 3, -1.0f, 4),
        set_param("coulomb -inf", 5, -INFINITY, 5),
        set_param("offset enabled 2", 6, 2.0f, 4),
        set_param("offset q -1e-9", 7, -1e-9f, 4),
        set_param("p0 -1", 8, -1.0f, 4),
        set_param("bandwidth 100 Hz", 9, 100.0f, 4),
        set_param("bandwidth 0", 9, 0.0f, 4),
        set_param("telemetry 1001 Hz", 10, 1001.0f, 4),
        set_param("telemetry 2.5 Hz", 10, 2.5f, 4),
        set_param("node id 0", 11, 0.0f, 4),
        set_param("node id 128", 11, 128.0f, 4),
        set_param("node id 1.5", 11, 1.5f, 4),
        set_param("calibration gain 0", 12, 0.0f, 4),
        set_param("calibration gain -6.6", 12, -6.6f, 4),
        set_param("calibration offset NaN", 13, NAN, 5),
        set_param("filter enabled 3", 15, 3.0f, 4),
        {"filter enable 2", NODE_CMD_ID, 8, 0, {0x01, 4, 2, 0, 0, 0, 0, 0}, 4},
        add_block("fixed 600 Hz", 0x12, 60000u, 1e-4f, 4),
        add_block("motor order 0", 0x10, 0u, 1e-4f, 4),
        add_block("motor q -1", 0x10, 200u, -1.0f, 4),
        add_block("output q NaN", 0x11, 100u, NAN, 5),
        {"block enable value 2", NODE_CMD_ID, 8, 0, {0x13, 3, 0, 2, 0, 0, 0, 0}, 4},
    };
    run_bad_commands(cmds, sizeof cmds / sizeof cmds[0], "can_out_of_range_config");
}

static void test_command_flood_is_bounded(void)
{
    /* 32 frames at once (the mock's whole receive queue): the tick takes
     * HD_FW_RX_PER_TICK a tick into its queue, the background answers, the
     * tick sends HD_FW_ACKS_PER_TICK ACKs a tick; every one answered, in
     * order, and the tick keeps its step */
    start_converged();
    hd_fw_config_t cfg_before;
    memcpy(&cfg_before, hd_fw_config(&rig.fw), sizeof cfg_before);
    for (unsigned i = 0; i < HAL_MOCK_RX_CAP; i++) {
        uint8_t d[8] = {0x77, (uint8_t)i, 0, 0, 0, 0, 0, 0};
        fi_push_cmd(&rig, d, 8, 0, NODE_CMD_ID);
    }
    uint32_t acks = rig.acks;
    uint64_t from = rig.tick;
    fi_rig_run(&rig, 1); /* queued; answered from the next tick on */
    TEST_ASSERT_EQUAL_UINT32(acks, rig.acks);
    fi_rig_run(&rig, 1);
    TEST_ASSERT_EQUAL_UINT32(acks + HD_FW_ACKS_PER_TICK, rig.acks);
    while (rig.acks < acks + HAL_MOCK_RX_CAP && rig.tick < from + 100u) {
        fi_rig_run(&rig, 1);
    }
    /* every tick after the first answers HD_FW_ACKS_PER_TICK */
    TEST_ASSERT_EQUAL_UINT64(from + 1u + HAL_MOCK_RX_CAP / HD_FW_ACKS_PER_TICK, rig.tick);
    TEST_ASSERT_EQUAL_UINT32(acks + HAL_MOCK_RX_CAP, rig.acks);
    rel_measured("can_command_flood", "frames=%u acks_per_tick=%u drain_ticks=%u",
                 (unsigned)HAL_MOCK_RX_CAP, (unsigned)HD_FW_ACKS_PER_TICK,
                 (unsigned)(rig.tick - from - 1u));
    TEST_ASSERT_EQUAL_UINT8(HAL_MOCK_RX_CAP - 1u, rig.last_ack[1]); /* in order */
    fi_rig_run(&rig, 500);
    assert_core_invariants();
    TEST_ASSERT_EQUAL_MEMORY(&cfg_before, hd_fw_config(&rig.fw), sizeof cfg_before);
    TEST_ASSERT_TRUE(fi_max_abs_err(&rig, T0, rig.tick) <= FI_BAND_NM);
}

static void test_implausible_gain_rejected_large_gain_flagged(void)
{
    /* A calibration gain of 3.4e38 N m/V would overflow gain x volts to +inf:
     * the firmware refuses it (OUT_OF_RANGE, calibration unchanged).  The
     * largest accepted gain (HD_FW_CALIB_GAIN_MAX_NM_PER_V) with 13 N m of
     * load gives ~2e4 N m: every sample must be flagged TORQUE_RANGE and
     * never reach the filter.  Restoring the gain recovers at once. */
    fi_rig_init(&rig, "duration_s = 16\nload_torque_profile = 0:13\n");
    fi_rig_run(&rig, T0);
    TEST_ASSERT_TRUE(fi_max_abs_err(&rig, T0 - 1000u, T0) <= FI_BAND_NM);
    const float gain_before = hd_fw_config(&rig.fw)->calib_gain_nm_per_v;
    bad_cmd_t huge = set_param("gain 3.4e38", 12, 3.4e38f, 0);
    fi_push_cmd(&rig, huge.data, 8, 0, NODE_CMD_ID);
    fi_rig_run(&rig, 100u);
    TEST_ASSERT_EQUAL_UINT8(HD_CAN_RES_OUT_OF_RANGE, rig.last_ack[2]);
    const uint8_t huge_result = rig.last_ack[2];
    TEST_ASSERT_EQUAL_FLOAT(gain_before, hd_fw_config(&rig.fw)->calib_gain_nm_per_v);
    TEST_ASSERT_TRUE(fi_max_abs_err(&rig, T0, T0 + 100u) <= FI_BAND_NM);

    bad_cmd_t large = set_param("gain max", 12, HD_FW_CALIB_GAIN_MAX_NM_PER_V, 0);
    fi_push_cmd(&rig, large.data, 8, 0, NODE_CMD_ID);
    fi_rig_run(&rig, 300u);
    TEST_ASSERT_EQUAL_UINT8(0, rig.last_ack[2]);
    uint16_t f = fi_faults_in(&rig, T0 + 102u, T0 + 400u);
    TEST_ASSERT_EQUAL_UINT16(HD_FAULT_TORQUE_RANGE, f & HD_FAULT_TORQUE_RANGE);
    bad_cmd_t back = set_param("gain nominal", 12, (float)rig.nom.gain_nm_per_v, 0);
    fi_push_cmd(&rig, back.data, 8, 0, NODE_CMD_ID);
    fi_rig_run(&rig, UINT64_MAX);
    assert_core_invariants();
    long rec = fi_recovery_ticks(&rig, T0 + 401u, FI_BAND_NM, FI_HOLD_TICKS);
    char extra[96];
    snprintf(extra, sizeof extra, "refused_gain=%.2g gain_limit=%g result=%u", 3.4e38,
             (double)HD_FW_CALIB_GAIN_MAX_NM_PER_V, (unsigned)huge_result);
    fi_report(&rig, "calibration_gain", rec, 20, (double)NAN, T0, T0 + 401u, extra);
    TEST_ASSERT_TRUE(rec >= 0 && rec <= 20);
}

int main(int argc, char **argv)
{
    if (UnityParseOptions(argc, argv) != 0) {
        return 1;
    }
    UNITY_BEGIN();
    RUN_TEST(test_tx_queue_full_500ms);
    RUN_TEST(test_bus_off_500ms_and_recovery);
    RUN_TEST(test_error_frames_and_other_ids_are_ignored);
    RUN_TEST(test_malformed_and_unknown_commands);
    RUN_TEST(test_out_of_range_configuration_rejected);
    RUN_TEST(test_command_flood_is_bounded);
    RUN_TEST(test_implausible_gain_rejected_large_gain_flagged);
    return UNITY_END();
}
