/* Commands on the mock HAL: parameters (every row of the table), filter
 * blocks, tare, calibration and configuration records, information,
 * reboot, bad and malformed frames; and the command plane's contract: the
 * tick only queues, the background executes, the next tick makes it live. */
#include <math.h>
#include <stdlib.h>

#include "fw_rig.h"
#include "hd_fw_records.h"

void setUp(void)
{
    rig_reset();
}
void tearDown(void) {}

static void test_set_and_get_parameters(void)
{
    init_fw();
    hd_can_ack_t a = set_param(HD_PARAM_R_NM2, 0.5f);
    TEST_ASSERT_EQUAL_UINT8(HD_CAN_RES_OK, a.result);
    TEST_ASSERT_EQUAL_UINT8(HD_CMD_SET_PARAM, a.opcode);
    TEST_ASSERT_EQUAL_UINT8(0x33, a.token);
    TEST_ASSERT_EQUAL_FLOAT(0.5f, a.value);
    TEST_ASSERT_EQUAL_FLOAT(0.5f, live_pipe()->kf.cfg.r_nm2); /* the running filter uses it */
    hd_can_cmd_t g = {0};
    g.opcode = HD_CMD_GET_PARAM;
    g.arg.get_param.id = HD_PARAM_R_NM2;
    a = send_cmd(&g);
    TEST_ASSERT_EQUAL_UINT8(HD_CAN_RES_OK, a.result);
    TEST_ASSERT_EQUAL_FLOAT(0.5f, a.value);
    TEST_ASSERT_EQUAL_UINT8(HD_CAN_RES_OK, set_param(HD_PARAM_GEAR_RATIO, 50.0f).result);
    TEST_ASSERT_EQUAL_FLOAT(50.0f, live_cfg()->gear_ratio);
    TEST_ASSERT_EQUAL_UINT8(HD_CAN_RES_OK, set_param(HD_PARAM_INERTIA_KGM2, 0.02f).result);
    TEST_ASSERT_EQUAL_FLOAT(0.02f, live_pipe()->expected.inertia_kgm2);
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
        hd_fw_config_t before_cfg = *live_cfg();
        hd_can_ack_t a = set_param(bad[i].id, bad[i].v);
        TEST_ASSERT_EQUAL_UINT8(bad[i].res, a.result);
        TEST_ASSERT_EQUAL_MEMORY(&before_cfg, live_cfg(), sizeof before_cfg);
    }
    TEST_ASSERT_TRUE((last_faults() & HD_FAULT_CMD_ERROR) != 0u);
    TEST_ASSERT_EQUAL_UINT32(13, hd_fw_counters(&fw)->command_errors);

    /* malformed frames on the command id: error ACK, nothing changed */
    hd_fw_config_t before_cfg = *live_cfg();
    hal_can_frame_t f = {0};
    f.id = id_of(HD_CAN_FRAME_CMD, 1);
    f.flags = HAL_CAN_FLAG_EXT;
    f.len = 3;
    f.data[0] = HD_CMD_SET_PARAM;
    f.data[1] = 5;
    uint32_t n0 = hal_mock_tx_count(&mock);
    hal_mock_push_rx(&mock, &f);
    f.len = 8;
    f.data[0] = 0x77; /* unknown opcode */
    hal_mock_push_rx(&mock, &f);
    f.data[0] = HD_CMD_SET_PARAM;
    f.flags = HAL_CAN_FLAG_EXT | HAL_CAN_FLAG_RTR;
    hal_mock_push_rx(&mock, &f);
    f.flags = HAL_CAN_FLAG_EXT;
    f.id = id_of(HD_CAN_FRAME_CMD, 2); /* another node: ignored, no reply */
    hal_mock_push_rx(&mock, &f);
    run(8, 1000, 1); /* 2 frames a tick in, 1 ACK a tick out */
    int results[3];
    unsigned n = 0;
    for (uint32_t i = n0; i < hal_mock_tx_count(&mock); i++) {
        const hal_can_frame_t *t = hal_mock_tx(&mock, i);
        TEST_ASSERT_TRUE(t->id != id_of(HD_CAN_FRAME_ACK, 2));
        if (t->id == id_of(HD_CAN_FRAME_ACK, 1) && n < 3) {
            results[n++] = t->data[2];
        }
    }
    TEST_ASSERT_EQUAL_UINT(3, n);
    TEST_ASSERT_EQUAL_INT(HD_CAN_RES_BAD_LENGTH, results[0]);
    TEST_ASSERT_EQUAL_INT(HD_CAN_RES_UNKNOWN_OPCODE, results[1]);
    TEST_ASSERT_EQUAL_INT(HD_CAN_RES_BAD_FRAME, results[2]);
    TEST_ASSERT_EQUAL_MEMORY(&before_cfg, live_cfg(), sizeof before_cfg);
}

static void test_filter_blocks_by_command(void)
{
    init_fw();
    unsigned n0 = live_cfg()->kf.block_count;
    hd_can_cmd_t c = {0};
    c.opcode = HD_CMD_ADD_FIXED;
    c.arg.add_fixed.frequency_hz = 50.0f;
    c.arg.add_fixed.q_nm2 = 1e-4f;
    hd_can_ack_t a = send_cmd(&c);
    TEST_ASSERT_EQUAL_UINT8(HD_CAN_RES_OK, a.result);
    TEST_ASSERT_EQUAL_UINT8(n0, a.aux);
    TEST_ASSERT_EQUAL_UINT8(n0 + 1, live_cfg()->kf.block_count);
    TEST_ASSERT_EQUAL_UINT8(HD_KF_LOCK_FIXED, live_cfg()->kf.blocks[n0].lock);
    TEST_ASSERT_EQUAL_FLOAT(50.0f, live_cfg()->kf.blocks[n0].order);
    c.arg.add_fixed.frequency_hz = 600.0f; /* over Nyquist */
    TEST_ASSERT_EQUAL_UINT8(HD_CAN_RES_OUT_OF_RANGE, send_cmd(&c).result);
    c.opcode = HD_CMD_ADD_MOTOR;
    c.arg.add_motor.order = 6.0f;
    c.arg.add_motor.q_nm2 = 1e-4f;
    while (live_cfg()->kf.block_count < HD_KF_MAX_BLOCKS) {
        TEST_ASSERT_EQUAL_UINT8(HD_CAN_RES_OK, send_cmd(&c).result);
    }
    hd_fw_config_t before = *live_cfg();
    TEST_ASSERT_EQUAL_UINT8(HD_CAN_RES_NO_SPACE, send_cmd(&c).result);
    TEST_ASSERT_EQUAL_MEMORY(&before, live_cfg(), sizeof before);

    hd_can_cmd_t e = {0};
    e.opcode = HD_CMD_BLOCK_ENABLE;
    e.arg.block_enable.index = 1;
    e.arg.block_enable.enable = 0;
    TEST_ASSERT_EQUAL_UINT8(HD_CAN_RES_OK, send_cmd(&e).result);
    TEST_ASSERT_EQUAL_UINT8(0, live_cfg()->kf.blocks[1].enabled);
    TEST_ASSERT_EQUAL_UINT8(0, live_pipe()->kf.cfg.blocks[1].enabled); /* the running filter too */
    e.arg.block_enable.index = 8;
    TEST_ASSERT_EQUAL_UINT8(HD_CAN_RES_BAD_INDEX, send_cmd(&e).result);

    /* read back, field by field (BLOCK_GET) */
    hd_can_cmd_t g = {0};
    g.opcode = HD_CMD_BLOCK_GET;
    g.arg.block_get.index = (uint8_t)n0;
    g.arg.block_get.field = 1u; /* order */
    TEST_ASSERT_EQUAL_FLOAT(50.0f, send_cmd(&g).value);
    g.arg.block_get.field = 0u; /* lock */
    TEST_ASSERT_EQUAL_FLOAT((float)HD_KF_LOCK_FIXED, send_cmd(&g).value);
    g.arg.block_get.field = 2u; /* q */
    TEST_ASSERT_EQUAL_FLOAT(1e-4f, send_cmd(&g).value);
    g.arg.block_get.index = 1u;
    g.arg.block_get.field = 3u; /* enabled: block 1 was disabled above */
    TEST_ASSERT_EQUAL_FLOAT(0.0f, send_cmd(&g).value);
    g.arg.block_get.field = 4u;
    TEST_ASSERT_EQUAL_UINT8(HD_CAN_RES_OUT_OF_RANGE, send_cmd(&g).result);
    g.arg.block_get.index = HD_KF_MAX_BLOCKS;
    g.arg.block_get.field = 0u;
    TEST_ASSERT_EQUAL_UINT8(HD_CAN_RES_BAD_INDEX, send_cmd(&g).result);

    hd_can_cmd_t clr = {0};
    clr.opcode = HD_CMD_BLOCKS_CLEAR;
    TEST_ASSERT_EQUAL_UINT8(HD_CAN_RES_OK, send_cmd(&clr).result);
    TEST_ASSERT_EQUAL_UINT8(0, live_cfg()->kf.block_count);
}

static void test_node_id_telemetry_rate_and_tare(void)
{
    init_fw();
    hd_can_ack_t a = set_param(HD_PARAM_NODE_ID, 5.0f);
    TEST_ASSERT_EQUAL_UINT8(HD_CAN_RES_OK, a.result);
    TEST_ASSERT_NOT_NULL(last_id(id_of(HD_CAN_FRAME_ACK, 1))); /* ACK from the old id */
    hal_mock_tx_clear(&mock);
    run(1, 1000, 1);
    TEST_ASSERT_EQUAL_UINT(1, count_id(id_of(HD_CAN_FRAME_TELEM_A, 5)));
    TEST_ASSERT_EQUAL_UINT(0, count_id(id_of(HD_CAN_FRAME_TELEM_A, 1)));

    TEST_ASSERT_EQUAL_UINT8(HD_CAN_RES_OK, set_param(HD_PARAM_TELEMETRY_RATE_HZ, 100.0f).result);
    hal_mock_tx_clear(&mock);
    run(100, 1000, 1);
    TEST_ASSERT_EQUAL_UINT(10, count_id(id_of(HD_CAN_FRAME_TELEM_A, 5)));

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
    hd_fw_isr(&fw);              /* no samples: the tick stops, the ACK goes out */
    hd_can_ack_t a;
    TEST_ASSERT_EQUAL_INT(0, hd_can_decode_ack(last_id(id_of(HD_CAN_FRAME_ACK, 1)), &a));
    TEST_ASSERT_EQUAL_UINT8(HD_CAN_RES_NO_DATA, a.result);
    TEST_ASSERT_EQUAL_FLOAT((float)OFFSET_V, live_cfg()->calib_offset_v);
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
    c.arg.calib_save.calibrated_unix_s = 1700000000u;
    hd_can_ack_t a = send_cmd(&c); /* send_cmd runs hd_fw_background */
    TEST_ASSERT_EQUAL_UINT8(HD_CAN_RES_OK, a.result);
    TEST_ASSERT_EQUAL_UINT8(HD_CMD_CALIB_SAVE, a.opcode);
    TEST_ASSERT_EQUAL_UINT8(9, a.token);
    /* read back independently of the firmware */
    hd_calib_storage_t s = storage();
    hd_calib_record_t rec;
    uint32_t seq;
    TEST_ASSERT_EQUAL_INT(HD_RECORD_OK, hd_calib_store_load(&s, &rec, &seq));
    TEST_ASSERT_EQUAL_FLOAT(6.5f, rec.gain_nm_per_v);
    TEST_ASSERT_EQUAL_FLOAT(-0.05f, rec.offset_v);
    TEST_ASSERT_EQUAL_UINT32(1700000000u, rec.calibrated_unix_s);
    run(1, 0, 1);
    TEST_ASSERT_EQUAL_HEX32(0, last_faults() & (HD_FAULT_CALIB_MISSING | HD_FAULT_CALIB_CORRUPT));

    /* change RAM, then reload from NVM */
    set_param(HD_PARAM_CALIB_GAIN_NM_PER_V, 9.0f);
    hd_can_cmd_t l = {0};
    l.opcode = HD_CMD_CALIB_LOAD;
    a = send_cmd(&l);
    TEST_ASSERT_EQUAL_UINT8(HD_CAN_RES_OK, a.result);
    TEST_ASSERT_EQUAL_FLOAT(6.5f, a.value);
    TEST_ASSERT_EQUAL_FLOAT(6.5f, live_cfg()->calib_gain_nm_per_v);

    /* NVM failure: error ACK, RAM calibration kept */
    mock.nvm_fail = true;
    a = send_cmd(&c);
    TEST_ASSERT_EQUAL_UINT8(HD_CAN_RES_NVM_ERROR, a.result);
    a = send_cmd(&l);
    TEST_ASSERT_EQUAL_UINT8(HD_CAN_RES_NVM_ERROR, a.result);
    TEST_ASSERT_EQUAL_FLOAT(6.5f, live_cfg()->calib_gain_nm_per_v);
}

static void test_random_frames_never_corrupt_the_state(void)
{
    init_fw();
    srand(12345);
    for (int i = 0; i < 3000; i++) {
        hal_can_frame_t f = {0};
        f.id = id_of(HD_CAN_FRAME_CMD, 1);
        f.flags = HAL_CAN_FLAG_EXT;
        f.len = (uint8_t)(rand() % 10 == 0 ? rand() % 9 : 8);
        for (int b = 0; b < 8; b++) {
            f.data[b] = (uint8_t)rand();
        }
        /* bias towards real opcodes so the argument checks are exercised */
        const uint8_t ops[] = {0x01, 0x10, 0x11, 0x12, 0x13, 0x20, 0x21, 0x40, 0x52, 0x60, 0x61};
        if (rand() % 2) {
            f.data[0] = ops[rand() % 11];
        }
        if ((f.data[0] == HD_CMD_SET_PARAM && f.data[2] == HD_PARAM_NODE_ID) ||
            f.data[0] == HD_CMD_CONFIG_LOAD) {
            continue; /* would move the node away from node 1 */
        }
        hd_fw_config_t before = *live_cfg();
        uint32_t n0 = hal_mock_tx_count(&mock);
        hd_fw_handle_frame(&fw, &f);
        motor += 1;
        hal_mock_push(&mock, 1000, motor);
        hd_fw_isr(&fw); /* applies the change, sends the ACK */
        const hal_can_frame_t *ack = NULL;
        for (uint32_t k = n0; k < hal_mock_tx_count(&mock); k++) {
            if (hal_mock_tx(&mock, k)->id == id_of(HD_CAN_FRAME_ACK, 1)) {
                ack = hal_mock_tx(&mock, k);
            }
        }
        TEST_ASSERT_NOT_NULL(ack);
        if (ack->data[2] != HD_CAN_RES_OK) {
            TEST_ASSERT_EQUAL_MEMORY(&before, live_cfg(), sizeof before);
        }
        TEST_ASSERT_EQUAL_INT(HD_FW_OK, hd_fw_config_check(live_cfg(), NULL));
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


/* The frame of "SET_PARAM r_nm2 = 0.25" (opcode replaceable) for node 1. */
static hal_can_frame_t r_frame(uint8_t opcode)
{
    hd_can_cmd_t c = {0};
    c.opcode = HD_CMD_SET_PARAM;
    c.arg.set_param.id = HD_PARAM_R_NM2;
    c.arg.set_param.value = 0.25f;
    hal_can_frame_t f;
    hd_can_encode_cmd(1, &c, &f);
    f.data[0] = opcode; /* byte 0: the opcode */
    return f;
}

static void test_the_tick_only_queues_commands(void)
{
    init_fw();
    run(1, 1000, 1);
    hal_can_frame_t f = r_frame(HD_CMD_SET_PARAM);
    hal_mock_push_rx(&mock, &f);
    for (int i = 0; i < 3; i++) { /* ticks without a background: nothing happens */
        motor += 1;
        hal_mock_push(&mock, 1000, motor);
        hd_fw_isr(&fw);
    }
    TEST_ASSERT_EQUAL_UINT32(0, hd_fw_counters(&fw)->commands);
    TEST_ASSERT_FALSE(live_cfg()->kf.r_nm2 == 0.25f);
    TEST_ASSERT_TRUE(hd_fw_background(&fw)); /* executed here, built in the spare slot */
    TEST_ASSERT_FALSE(live_pipe()->kf.cfg.r_nm2 == 0.25f); /* not live before a tick */
    TEST_ASSERT_EQUAL_UINT8(1, fw.request.pending);
    motor += 1;
    hal_mock_push(&mock, 1000, motor);
    hd_fw_isr(&fw); /* swapped in at the tick boundary */
    TEST_ASSERT_EQUAL_FLOAT(0.25f, live_pipe()->kf.cfg.r_nm2);
    TEST_ASSERT_EQUAL_UINT8(0, fw.request.pending);
}

/* A background that falls behind (no background between 12 ticks, 20
 * commands waiting): the tick fills the command queue, then leaves the rest
 * with the driver and counts each such tick; once the background runs,
 * every command is answered, none lost. */
static void test_a_full_command_queue_is_back_pressure_counted(void)
{
    init_fw();
    run(1, 1000, 1);
    const unsigned frames = 20u, ticks = 12u;
    for (unsigned i = 0; i < frames; i++) {
        hal_can_frame_t f = r_frame(HD_CMD_GET_PARAM);
        hal_mock_push_rx(&mock, &f);
    }
    for (unsigned i = 0; i < ticks; i++) {
        motor += 1;
        hal_mock_push(&mock, 1000, motor);
        hd_fw_isr(&fw);
    }
    /* HD_FW_RX_PER_TICK a tick until the queue holds HD_FW_QUEUE_LEN */
    const unsigned filling = HD_FW_QUEUE_LEN / HD_FW_RX_PER_TICK;
    TEST_ASSERT_EQUAL_UINT32(ticks - filling, hd_fw_counters(&fw)->command_queue_full);
    run(40, 1000, 1); /* its first tick still finds the queue full: one more */
    TEST_ASSERT_EQUAL_UINT32(frames, hd_fw_counters(&fw)->commands);
    TEST_ASSERT_EQUAL_UINT32(ticks - filling + 1u,
                             simple_cmd(HD_CMD_INFO, HD_INFO_COMMAND_QUEUE_FULL).value_u32);
}

static void test_a_direct_caller_gets_busy_while_a_change_is_pending(void)
{
    init_fw();
    hal_can_frame_t f = r_frame(HD_CMD_SET_PARAM);
    hd_fw_handle_frame(&fw, &f);
    f = r_frame(HD_CMD_CONFIG_SAVE); /* a model change has not reached the tick */
    hd_fw_handle_frame(&fw, &f);
    run(2, 1000, 1);
    hd_can_ack_t a;
    TEST_ASSERT_EQUAL_INT(0, hd_can_decode_ack(last_id(id_of(HD_CAN_FRAME_ACK, 1)), &a));
    TEST_ASSERT_EQUAL_UINT8(HD_CMD_CONFIG_SAVE, a.opcode);
    TEST_ASSERT_EQUAL_UINT8(HD_CAN_RES_BUSY, a.result);
    TEST_ASSERT_EQUAL_FLOAT(0.25f, live_cfg()->kf.r_nm2); /* the first one took effect */
}

/* A value inside each row's range, away from the defaults. */
static float probe_value(const hd_param_info_t *p)
{
    if (p->type == HD_PT_BOOL) {
        return 1.0f;
    }
    float lo = p->lo, hi = p->hi;
    float v = (hi > 1000.0f) ? lo + 3.0f : 0.5f * (lo + hi);
    if ((p->flags & HD_PF_LO_OPEN) && v <= lo) {
        v = lo + 0.5f;
    }
    return p->type == HD_PT_F32 ? v : (float)(int32_t)v;
}

static void test_every_parameter_of_the_table_over_can(void)
{
    init_fw();
    unsigned settable = 0;
    for (size_t i = 0; i < hd_param_count(); i++) {
        const hd_param_info_t *p = hd_param_at(i);
        if (p->id == HD_PARAM_NODE_ID) {
            continue; /* moves the node: test_node_id_... */
        }
        hal_mock_tx_clear(&mock); /* room in the transmit log for this row's ACKs */
        hd_can_ack_t a = set_param(p->id, probe_value(p));
        if (p->flags & HD_PF_RO) {
            TEST_ASSERT_EQUAL_UINT8(HD_CAN_RES_READ_ONLY, a.result);
            continue;
        }
        /* A few rows are valid alone but refused as a model (p0 / R). */
        if (a.result == HD_CAN_RES_REJECTED) {
            continue;
        }
        TEST_ASSERT_EQUAL_UINT8_MESSAGE(HD_CAN_RES_OK, a.result, p->key);
        hd_can_ack_t g = simple_cmd(HD_CMD_GET_PARAM, p->id);
        TEST_ASSERT_EQUAL_FLOAT_MESSAGE(probe_value(p), g.value, p->key);
        TEST_ASSERT_EQUAL_FLOAT(probe_value(p), hd_param_get(p, live_cfg()));
        set_param(p->id, hd_param_get(p, &cfg)); /* back to the boot defaults */
        settable++;
    }
    TEST_ASSERT_TRUE(settable >= 25u);
}

static hd_can_ack_t info(uint8_t opcode, uint8_t item)
{
    return simple_cmd(opcode, item);
}

static void test_version_and_info(void)
{
    mock.board_id = 0x54534F48u; /* "HOST" */
    hal_mock_bind(&mock, &hal);
    init_fw();
    hd_can_ack_t a = info(HD_CMD_VERSION, HD_INFO_PROTOCOL_VERSION);
    TEST_ASSERT_EQUAL_UINT8(HD_CAN_RES_OK, a.result);
    TEST_ASSERT_EQUAL_UINT32(2u, a.value_u32); /* docs/reference/protocol.md: version 2 */
    TEST_ASSERT_EQUAL_HEX32(0x54534F48u, info(HD_CMD_VERSION, HD_INFO_BOARD_ID).value_u32);
    TEST_ASSERT_EQUAL_UINT32(HD_CONFIG_RECORD_VERSION,
                             info(HD_CMD_VERSION, HD_INFO_CONFIG_RECORD_VERSION).value_u32);
    TEST_ASSERT_EQUAL_UINT8(HD_CAN_RES_BAD_INDEX, info(HD_CMD_VERSION, 16).result);
    TEST_ASSERT_EQUAL_UINT8(HD_CAN_RES_BAD_INDEX, info(HD_CMD_INFO, 3).result);
    TEST_ASSERT_EQUAL_UINT8(HD_CAN_RES_BAD_INDEX, info(HD_CMD_INFO, 200).result);
    uint32_t ticks = info(HD_CMD_INFO, HD_INFO_TICKS).value_u32;
    TEST_ASSERT_EQUAL_UINT32(hd_fw_counters(&fw)->ticks - 1u, ticks); /* read a tick ago */
    TEST_ASSERT_EQUAL_UINT32(0u, info(HD_CMD_INFO, HD_INFO_FAULT_PC).value_u32);
}

/* What the HAL saw below the firmware reaches INFO: the board's failed
 * drivers at boot, the CAN controller's lost frames, error frames and
 * bus-off events (otherwise counted in the driver and lost to the user). */
static void test_info_reports_what_the_hal_counted(void)
{
    mock.boot.init_errors = 0x14u;
    init_fw();
    mock.counters.can_rx_overruns = 7u;
    mock.counters.can_error_frames = 3u;
    mock.counters.can_bus_off = 2u;
    mock.counters.can_tx_aborted = 5u;
    mock.counters.can_tx_error_count = 128u;
    mock.counters.can_rx_error_count = 9u;
    TEST_ASSERT_EQUAL_HEX32(0x14u, info(HD_CMD_INFO, HD_INFO_BOARD_INIT_ERRORS).value_u32);
    TEST_ASSERT_EQUAL_UINT32(7u, info(HD_CMD_INFO, HD_INFO_CAN_RX_OVERRUNS).value_u32);
    TEST_ASSERT_EQUAL_UINT32(3u, info(HD_CMD_INFO, HD_INFO_CAN_ERROR_FRAMES).value_u32);
    TEST_ASSERT_EQUAL_UINT32(2u, info(HD_CMD_INFO, HD_INFO_CAN_BUS_OFF).value_u32);
    TEST_ASSERT_EQUAL_UINT32(5u, info(HD_CMD_INFO, HD_INFO_CAN_TX_ABORTED).value_u32);
    TEST_ASSERT_EQUAL_UINT32(128u, info(HD_CMD_INFO, HD_INFO_CAN_TX_ERROR_COUNT).value_u32);
    TEST_ASSERT_EQUAL_UINT32(9u, info(HD_CMD_INFO, HD_INFO_CAN_RX_ERROR_COUNT).value_u32);
    TEST_ASSERT_EQUAL_UINT8(HD_CAN_RES_BAD_INDEX, info(HD_CMD_VERSION, HD_INFO_CAN_BUS_OFF).result);
}

static void test_reboot_after_the_ack(void)
{
    init_fw();
    TEST_ASSERT_EQUAL_UINT8(HD_CAN_RES_UNSUPPORTED, simple_cmd(HD_CMD_REBOOT, 0).result);
    mock.reboot_supported = true;
    hal_mock_bind(&mock, &hal);
    init_fw();
    hd_can_ack_t a = simple_cmd(HD_CMD_REBOOT, 0);
    TEST_ASSERT_EQUAL_UINT8(HD_CAN_RES_OK, a.result); /* the ACK got out ... */
    run(1, 1000, 1);
    TEST_ASSERT_EQUAL_UINT32(1, mock.reboots);        /* ... then the restart */
}

static void test_configuration_survives_a_reboot(void)
{
    init_fw();
    TEST_ASSERT_EQUAL_UINT8(HD_CAN_RES_OK, set_param(HD_PARAM_R_NM2, 0.125f).result);
    TEST_ASSERT_EQUAL_UINT8(HD_CAN_RES_OK, set_param(HD_PARAM_TELEMETRY_RATE_HZ, 200.0f).result);
    hd_can_cmd_t c = {0};
    c.opcode = HD_CMD_ADD_MOTOR;
    c.arg.add_motor.order = 6.0f;
    c.arg.add_motor.q_nm2 = 2e-7f;
    TEST_ASSERT_EQUAL_UINT8(HD_CAN_RES_OK, send_cmd(&c).result);
    TEST_ASSERT_EQUAL_UINT8(HD_CAN_RES_OK, simple_cmd(HD_CMD_CONFIG_SAVE, 0).result);
    hd_fw_config_t saved = *live_cfg();
    init_fw(); /* power cycle: the same NVM, the same build defaults */
    TEST_ASSERT_EQUAL_MEMORY(&saved, live_cfg(), sizeof saved);
    TEST_ASSERT_EQUAL_INT(HD_RECORD_OK, hd_fw_record_status(&fw, HD_RECORD_KIND_CONFIG));
    TEST_ASSERT_EQUAL_FLOAT(0.125f, live_pipe()->kf.cfg.r_nm2);
    run(1, 1000, 1);
    hd_can_boot_t b;
    TEST_ASSERT_EQUAL_INT(0, hd_can_decode_boot(last_id(id_of(HD_CAN_FRAME_BOOT, 1)), &b));
    TEST_ASSERT_TRUE(b.config_from_record);
    /* defaults in RAM, the record untouched; load brings it back */
    TEST_ASSERT_EQUAL_UINT8(HD_CAN_RES_OK, simple_cmd(HD_CMD_CONFIG_DEFAULTS, 0).result);
    TEST_ASSERT_EQUAL_FLOAT(cfg.kf.r_nm2, live_cfg()->kf.r_nm2);
    TEST_ASSERT_EQUAL_UINT8(HD_CAN_RES_OK, simple_cmd(HD_CMD_CONFIG_LOAD, 0).result);
    TEST_ASSERT_EQUAL_MEMORY(&saved, live_cfg(), sizeof saved);
}

static void test_save_right_after_a_change_saves_the_change(void)
{
    init_fw();
    hd_can_cmd_t c = {0};
    hal_can_frame_t f;
    c.opcode = HD_CMD_SET_PARAM;
    c.arg.set_param.id = HD_PARAM_GEAR_RATIO;
    c.arg.set_param.value = 121.0f;
    hd_can_encode_cmd(1, &c, &f);
    hal_mock_push_rx(&mock, &f);
    c.opcode = HD_CMD_CONFIG_SAVE; /* in the same tick, right behind it */
    hd_can_encode_cmd(1, &c, &f);
    hal_mock_push_rx(&mock, &f);
    run(4, 1000, 1);
    hd_store_io_t io = storage();
    uint8_t buf[HD_CONFIG_RECORD_MAX];
    size_t len = 0;
    TEST_ASSERT_EQUAL_INT(HD_RECORD_OK, hd_store_load(&io, HD_RECORD_KIND_CONFIG,
                                                      HD_CONFIG_RECORD_VERSION, buf, sizeof buf,
                                                      &len, NULL, NULL));
    hd_fw_config_t back;
    TEST_ASSERT_EQUAL_INT(HD_RECORD_OK, hd_config_record_decode(buf, len, &cfg, &back));
    TEST_ASSERT_EQUAL_FLOAT(121.0f, back.gear_ratio);
}

static void test_unusable_saved_configuration_boots_defaults_with_a_flag(void)
{
    init_fw();
    set_param(HD_PARAM_R_NM2, 0.125f);
    simple_cmd(HD_CMD_CONFIG_SAVE, 0);
    /* a record of another version, written by some other firmware */
    uint8_t buf[HD_CONFIG_RECORD_MAX];
    size_t len = hd_config_record_encode(live_cfg(), buf, sizeof buf);
    hd_store_io_t io = storage();
    TEST_ASSERT_EQUAL_INT(HD_RECORD_OK, hd_store_save(&io, HD_RECORD_KIND_CONFIG, 99u, buf, len));
    init_fw();
    TEST_ASSERT_EQUAL_INT(HD_RECORD_BAD_VERSION, hd_fw_record_status(&fw, HD_RECORD_KIND_CONFIG));
    TEST_ASSERT_EQUAL_FLOAT(cfg.kf.r_nm2, live_cfg()->kf.r_nm2);
    run(1, 1000, 1);
    TEST_ASSERT_TRUE((last_faults() & HD_FAULT_CONFIG_DEFAULTS) != 0u);
    TEST_ASSERT_EQUAL_UINT8(HD_RECORD_BAD_VERSION,
                            last_id(id_of(HD_CAN_FRAME_HEARTBEAT, 1))->data[6] >> 4);
    /* an intact record holding an out-of-range value (a buggy writer) */
    buf[1 + 1] ^= 0xFFu; /* the first parameter's value bytes */
    buf[1 + 4] = 0x7Fu;
    TEST_ASSERT_EQUAL_INT(HD_RECORD_OK, hd_store_save(&io, HD_RECORD_KIND_CONFIG,
                                                      HD_CONFIG_RECORD_VERSION, buf, len));
    init_fw();
    TEST_ASSERT_EQUAL_INT(HD_RECORD_CORRUPT, hd_fw_record_status(&fw, HD_RECORD_KIND_CONFIG));
    /* CONFIG_SAVE repairs it and clears the flag */
    TEST_ASSERT_EQUAL_UINT8(HD_CAN_RES_OK, simple_cmd(HD_CMD_CONFIG_SAVE, 0).result);
    run(1, 1000, 1);
    TEST_ASSERT_EQUAL_HEX32(0, last_faults() & HD_FAULT_CONFIG_DEFAULTS);
    /* load with nothing saved says so */
    memset(mock.nvm, 0xFF, sizeof mock.nvm);
    TEST_ASSERT_EQUAL_UINT8(HD_CAN_RES_NO_DATA, simple_cmd(HD_CMD_CONFIG_LOAD, 0).result);
}

/* A record from an older firmware holds an id since retired (hd_params.def,
 * HD_PARAM_RETIRED): skipped, the rest used; an id this firmware never had
 * is a newer firmware's record: refused. */
static void test_saved_configuration_with_a_retired_id_still_loads(void)
{
    init_fw();
    hd_fw_config_t mine = *live_cfg();
    mine.kf.r_nm2 = 0.125f;
    uint8_t rec[HD_CONFIG_RECORD_MAX];
    size_t len = hd_config_record_encode(&mine, rec, sizeof rec);
    TEST_ASSERT_TRUE(len > 0u && len + 5u <= sizeof rec);
    uint8_t old[HD_CONFIG_RECORD_MAX];
    old[0] = (uint8_t)(rec[0] + 1u);
    old[1] = 39u; /* predict_increment, retired */
    const uint8_t one_f32[4] = {0x00, 0x00, 0x80, 0x3F};
    memcpy(old + 2, one_f32, sizeof one_f32);
    memcpy(old + 6, rec + 1, len - 1u);
    hd_fw_config_t back;
    TEST_ASSERT_EQUAL_INT(HD_RECORD_OK, hd_config_record_decode(old, len + 5u, &cfg, &back));
    TEST_ASSERT_EQUAL_FLOAT(0.125f, back.kf.r_nm2);
    TEST_ASSERT_EQUAL_UINT8(mine.kf.block_count, back.kf.block_count);
    old[1] = 200u; /* no firmware of this table had it */
    TEST_ASSERT_EQUAL_INT(HD_RECORD_BAD_VERSION, hd_config_record_decode(old, len + 5u, &cfg, &back));
    TEST_ASSERT_TRUE(hd_param_is_retired(39u));
    TEST_ASSERT_NULL(hd_param_by_id(39u));
}

static void test_block_toggle_keeps_the_other_estimates(void)
{
    cfg.filter_enabled = 1;
    init_fw();
    /* a ripple for the order-2 block to learn */
    for (int i = 0; i < 400; i++) {
        motor += 20;
        double th = 2.0 * 2.0 * TEST_PI * (double)motor / CPR;
        int32_t counts = (int32_t)lround((0.5 * cos(th) / GAIN + OFFSET_V) / VPC);
        hal_mock_push(&mock, counts, motor);
        hd_fw_isr(&fw);
        hd_fw_background(&fw);
    }
    float x0 = hd_kf_state(&live_pipe()->kf, 0);
    float x1 = hd_kf_state(&live_pipe()->kf, 1);
    TEST_ASSERT_TRUE(x0 * x0 + x1 * x1 > 0.01f); /* it learned something */
    hd_can_cmd_t e = {0};
    e.opcode = HD_CMD_BLOCK_ENABLE;
    e.arg.block_enable.index = 1; /* order 4 off */
    e.arg.block_enable.enable = 0;
    hal_can_frame_t f;
    hd_can_encode_cmd(1, &e, &f);
    hd_fw_handle_frame(&fw, &f);
    TEST_ASSERT_EQUAL_UINT8(HD_FW_REQ_SETTINGS | HD_FW_REQ_BLOCK, fw.request.flags);
    run(1, (int32_t)lround(OFFSET_V / VPC), 20); /* the tick applies it, then one step */
    TEST_ASSERT_EQUAL_UINT8(0, live_cfg()->kf.blocks[1].enabled);
    /* Block 0 kept its estimate (a rebuild would have restarted it at 0). */
    float y0 = hd_kf_state(&live_pipe()->kf, 0);
    float y1 = hd_kf_state(&live_pipe()->kf, 1);
    TEST_ASSERT_TRUE(y0 * y0 + y1 * y1 > 0.8f * (x0 * x0 + x1 * x1));
}

int main(int argc, char **argv)
{
    if (UnityParseOptions(argc, argv) != 0) {
        return 1;
    }
    UNITY_BEGIN();
    RUN_TEST(test_set_and_get_parameters);
    RUN_TEST(test_rejected_commands_change_nothing);
    RUN_TEST(test_filter_blocks_by_command);
    RUN_TEST(test_node_id_telemetry_rate_and_tare);
    RUN_TEST(test_tare_without_samples_is_refused);
    RUN_TEST(test_calibration_save_and_load_by_command);
    RUN_TEST(test_random_frames_never_corrupt_the_state);
    RUN_TEST(test_the_tick_only_queues_commands);
    RUN_TEST(test_a_full_command_queue_is_back_pressure_counted);
    RUN_TEST(test_a_direct_caller_gets_busy_while_a_change_is_pending);
    RUN_TEST(test_every_parameter_of_the_table_over_can);
    RUN_TEST(test_version_and_info);
    RUN_TEST(test_info_reports_what_the_hal_counted);
    RUN_TEST(test_reboot_after_the_ack);
    RUN_TEST(test_configuration_survives_a_reboot);
    RUN_TEST(test_save_right_after_a_change_saves_the_change);
    RUN_TEST(test_unusable_saved_configuration_boots_defaults_with_a_flag);
    RUN_TEST(test_saved_configuration_with_a_retired_id_still_loads);
    RUN_TEST(test_block_toggle_keeps_the_other_estimates);
    return UNITY_END();
}
