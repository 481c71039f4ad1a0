/* CAN protocol: byte layouts checked against hand-computed bytes from the
 * tables in docs/reference/protocol.md, identifiers, round trips, saturation,
 * malformed frames. */
#include <math.h>
#include <string.h>

#include "hal_mock.h"
#include "hd_can_proto.h"
#include "hd_params.h"
#include "hd_record_store.h"
#include "unity.h"

void setUp(void) {}
void tearDown(void) {}

static void test_telem_bytes_match_the_documented_layout(void)
{
    hd_can_telem_t t = {0};
    t.torque_filtered_nm = 12.34f;   /* 1234 = 0x04D2 */
    t.torque_raw_nm = -1.5f;         /* -150 = 0xFF6A */
    t.ripple_nm = 0.25f;             /* 250 = 0x00FA at 1 mNm */
    t.torque_valid = true;
    t.motor_velocity_rad_s = 156.0f; /* 156000 = 0x00026160 */
    t.faults = 0x018410u;           /* a fault bit above 16 travels too */
    t.kf_status = 0x05u;
    t.seq = 0x7Fu;
    hal_can_frame_t a, b;
    hd_can_encode_telem(3, &t, &a, &b);
    const uint8_t ea[8] = {0xD2, 0x04, 0x6A, 0xFF, 0xFA, 0x00, 0x7F, 0x00};
    const uint8_t eb[8] = {0x60, 0x61, 0x02, 0x10, 0x84, 0x01, 0x05, 0x7F};
    TEST_ASSERT_EQUAL_HEX32(0x01D00203u, a.id); /* prefix 0x01D0, type 0x02, node 3 */
    TEST_ASSERT_EQUAL_HEX32(0x01D00303u, b.id);
    TEST_ASSERT_EQUAL_UINT8(HAL_CAN_FLAG_EXT, a.flags);
    TEST_ASSERT_EQUAL_UINT8(8, a.len);
    TEST_ASSERT_EQUAL_MEMORY(ea, a.data, 8);
    TEST_ASSERT_EQUAL_MEMORY(eb, b.data, 8);

    hd_can_telem_t d;
    TEST_ASSERT_EQUAL_INT(0, hd_can_decode_telem(&a, &b, &d));
    TEST_ASSERT_TRUE(d.torque_valid);
    TEST_ASSERT_FLOAT_WITHIN(1e-5, 12.34, d.torque_filtered_nm);
    TEST_ASSERT_FLOAT_WITHIN(1e-5, -1.5, d.torque_raw_nm);
    TEST_ASSERT_FLOAT_WITHIN(1e-6, 0.25, d.ripple_nm);
    TEST_ASSERT_FLOAT_WITHIN(1e-3, 156.0, d.motor_velocity_rad_s);
    TEST_ASSERT_EQUAL_HEX32(0x018410u, d.faults);
    TEST_ASSERT_EQUAL_UINT8(0x7Fu, d.seq);
}

static void test_telem_saturates_and_marks_not_available(void)
{
    TEST_ASSERT_EQUAL_INT(32767, hd_can_scale_i16(400.0f, 0.01f));
    TEST_ASSERT_EQUAL_INT(-32767, hd_can_scale_i16(-400.0f, 0.01f));
    TEST_ASSERT_EQUAL_INT(-32768, hd_can_scale_i16(NAN, 0.01f));
    TEST_ASSERT_EQUAL_INT(-32768, hd_can_scale_i16(INFINITY, 0.01f));
    TEST_ASSERT_EQUAL_INT(-2, hd_can_scale_i16(-0.015f, 0.01f)); /* rounds half away */
    hd_can_telem_t t = {0};
    t.torque_filtered_nm = 1.0f;
    t.torque_raw_nm = 1.0f;
    t.torque_valid = false;
    hal_can_frame_t a, b;
    hd_can_encode_telem(1, &t, &a, &b);
    TEST_ASSERT_EQUAL_HEX8(0x00, a.data[0]);
    TEST_ASSERT_EQUAL_HEX8(0x80, a.data[1]);
    hd_can_telem_t d;
    TEST_ASSERT_EQUAL_INT(0, hd_can_decode_telem(&a, &b, &d));
    TEST_ASSERT_FALSE(d.torque_valid);
    b.data[7] ^= 1u; /* sequence mismatch: not a pair */
    TEST_ASSERT_EQUAL_INT(-1, hd_can_decode_telem(&a, &b, &d));
}

static void test_command_bytes_match_the_documented_example(void)
{
    /* docs/reference/protocol.md: 01D01001#1007C80000007A44 adds motor order 2, q = 1000 */
    hd_can_cmd_t c = {0};
    c.opcode = HD_CMD_ADD_MOTOR;
    c.token = 7;
    c.arg.add_motor.order = 2.0f;
    c.arg.add_motor.q_nm2 = 1000.0f;
    hal_can_frame_t f;
    hd_can_encode_cmd(1, &c, &f);
    const uint8_t e[8] = {0x10, 0x07, 0xC8, 0x00, 0x00, 0x00, 0x7A, 0x44};
    TEST_ASSERT_EQUAL_HEX32(0x01D01001u, f.id);
    TEST_ASSERT_EQUAL_MEMORY(e, f.data, 8);
    hd_can_cmd_t d;
    TEST_ASSERT_EQUAL_INT(HD_CAN_RES_OK, hd_can_decode_cmd(&f, &d));
    TEST_ASSERT_EQUAL_UINT8(HD_CMD_ADD_MOTOR, d.opcode);
    TEST_ASSERT_EQUAL_UINT8(7, d.token);
    TEST_ASSERT_EQUAL_FLOAT(2.0f, d.arg.add_motor.order);
    TEST_ASSERT_EQUAL_FLOAT(1000.0f, d.arg.add_motor.q_nm2);
}

static void test_command_argument_bytes(void)
{
    /* Hand-computed from docs/reference/protocol.md's argument table. */
    hd_can_cmd_t c = {0};
    hal_can_frame_t f;
    c.opcode = HD_CMD_ADD_FIXED;
    c.token = 1;
    c.arg.add_fixed.frequency_hz = 499.996f; /* x100 rounds to 50000 = 0xC350 */
    c.arg.add_fixed.q_nm2 = -2.0f;           /* 0xC0000000 */
    hd_can_encode_cmd(1, &c, &f);
    const uint8_t ef[8] = {0x12, 0x01, 0x50, 0xC3, 0x00, 0x00, 0x00, 0xC0};
    TEST_ASSERT_EQUAL_MEMORY(ef, f.data, 8);
    c.arg.add_fixed.frequency_hz = 700.0f;   /* clamps at 0xFFFF */
    hd_can_encode_cmd(1, &c, &f);
    TEST_ASSERT_EQUAL_HEX8(0xFF, f.data[2]);
    TEST_ASSERT_EQUAL_HEX8(0xFF, f.data[3]);
    c = (hd_can_cmd_t){0};
    c.opcode = HD_CMD_BLOCK_GET;
    c.token = 0xAB;
    c.arg.block_get.index = 5;
    c.arg.block_get.field = HD_BLOCK_FIELD_Q_NM2;
    hd_can_encode_cmd(1, &c, &f);
    const uint8_t eg[8] = {0x15, 0xAB, 0x05, 0x02, 0x00, 0x00, 0x00, 0x00};
    TEST_ASSERT_EQUAL_MEMORY(eg, f.data, 8);
    c = (hd_can_cmd_t){0};
    c.opcode = HD_CMD_PROFILE_PUT;
    c.arg.profile_put.line = 0x13;   /* line 3, b */
    c.arg.profile_put.order = 2;
    c.arg.profile_put.value_nm = NAN; /* passed on: the handler refuses it */
    hd_can_encode_cmd(1, &c, &f);
    TEST_ASSERT_EQUAL_HEX8(0x13, f.data[2]);
    TEST_ASSERT_EQUAL_HEX8(0x02, f.data[3]);
    hd_can_cmd_t d;
    TEST_ASSERT_EQUAL_INT(HD_CAN_RES_OK, hd_can_decode_cmd(&f, &d));
    TEST_ASSERT_TRUE(isnan(d.arg.profile_put.value_nm));
}

static void test_command_round_trips(void)
{
    const uint8_t bare[] = {HD_CMD_BLOCKS_CLEAR, HD_CMD_TARE, HD_CMD_CALIB_LOAD,
                            HD_CMD_FILTER_RESET, HD_CMD_CONFIG_SAVE, HD_CMD_REBOOT};
    hal_can_frame_t f;
    hd_can_cmd_t d;
    for (unsigned i = 0; i < sizeof bare; i++) {
        hd_can_cmd_t c = {0};
        c.opcode = bare[i];
        c.token = (uint8_t)(i * 37u);
        hd_can_encode_cmd(9, &c, &f);
        TEST_ASSERT_EQUAL_INT(HD_CAN_RES_OK, hd_can_decode_cmd(&f, &d));
        TEST_ASSERT_EQUAL_UINT8(c.opcode, d.opcode);
        TEST_ASSERT_EQUAL_UINT8(c.token, d.token);
        const uint8_t zero[6] = {0};
        TEST_ASSERT_EQUAL_MEMORY(zero, &f.data[2], 6);
    }
    hd_can_cmd_t c = {0};
    c.opcode = HD_CMD_BLOCK_ENABLE;
    c.arg.block_enable.index = 2;
    c.arg.block_enable.enable = 1;
    hd_can_encode_cmd(9, &c, &f);
    TEST_ASSERT_EQUAL_INT(HD_CAN_RES_OK, hd_can_decode_cmd(&f, &d));
    TEST_ASSERT_EQUAL_UINT8(2, d.arg.block_enable.index);
    TEST_ASSERT_EQUAL_UINT8(1, d.arg.block_enable.enable);
    c = (hd_can_cmd_t){0};
    c.opcode = HD_CMD_SET_PARAM;
    c.arg.set_param.id = 2;
    c.arg.set_param.value = -0.125f;
    hd_can_encode_cmd(9, &c, &f);
    TEST_ASSERT_EQUAL_INT(HD_CAN_RES_OK, hd_can_decode_cmd(&f, &d));
    TEST_ASSERT_EQUAL_UINT8(2, d.arg.set_param.id);
    TEST_ASSERT_EQUAL_FLOAT(-0.125f, d.arg.set_param.value);
    c = (hd_can_cmd_t){0};
    c.opcode = HD_CMD_CALIB_SAVE;
    c.arg.calib_save.calibrated_unix_s = 1700000000u;
    hd_can_encode_cmd(1, &c, &f);
    TEST_ASSERT_EQUAL_HEX8(0x00, f.data[4]); /* 1700000000 = 0x6553F100 */
    TEST_ASSERT_EQUAL_HEX8(0xF1, f.data[5]);
    TEST_ASSERT_EQUAL_HEX8(0x53, f.data[6]);
    TEST_ASSERT_EQUAL_HEX8(0x65, f.data[7]);
    TEST_ASSERT_EQUAL_INT(HD_CAN_RES_OK, hd_can_decode_cmd(&f, &d));
    TEST_ASSERT_EQUAL_UINT32(1700000000u, d.arg.calib_save.calibrated_unix_s);
}

static void test_malformed_commands_are_classified(void)
{
    hd_can_cmd_t c = {0};
    c.opcode = HD_CMD_SET_PARAM;
    c.token = 42;
    c.arg.set_param.id = HD_PARAM_R_NM2;
    c.arg.set_param.value = 1.0f;
    hal_can_frame_t good;
    hd_can_encode_cmd(1, &c, &good);
    hd_can_cmd_t d;

    hal_can_frame_t f = good;
    f.len = 5;
    TEST_ASSERT_EQUAL_INT(HD_CAN_RES_BAD_LENGTH, hd_can_decode_cmd(&f, &d));
    TEST_ASSERT_EQUAL_UINT8(42, d.token); /* still echoed */
    TEST_ASSERT_EQUAL_UINT8(0, d.arg.set_param.id); /* arguments only when OK */
    f = good;
    f.len = 1;
    TEST_ASSERT_EQUAL_INT(HD_CAN_RES_BAD_LENGTH, hd_can_decode_cmd(&f, &d));
    TEST_ASSERT_EQUAL_UINT8(HD_CMD_SET_PARAM, d.opcode);
    TEST_ASSERT_EQUAL_UINT8(0, d.token); /* not in the frame */
    f = good;
    f.len = 0;
    TEST_ASSERT_EQUAL_INT(HD_CAN_RES_BAD_LENGTH, hd_can_decode_cmd(&f, &d));
    TEST_ASSERT_EQUAL_UINT8(0, d.opcode);
    f = good;
    f.flags = HAL_CAN_FLAG_EXT | HAL_CAN_FLAG_RTR;
    TEST_ASSERT_EQUAL_INT(HD_CAN_RES_BAD_FRAME, hd_can_decode_cmd(&f, &d));
    f = good;
    f.flags = HAL_CAN_FLAG_EXT | HAL_CAN_FLAG_FD;
    TEST_ASSERT_EQUAL_INT(HD_CAN_RES_BAD_FRAME, hd_can_decode_cmd(&f, &d));
    f = good;
    f.data[0] = 0x99;
    TEST_ASSERT_EQUAL_INT(HD_CAN_RES_UNKNOWN_OPCODE, hd_can_decode_cmd(&f, &d));
    f = good;
    f.data[0] = HD_CMD_SETPOINT_REFUSED; /* an answer, not a command */
    TEST_ASSERT_EQUAL_INT(HD_CAN_RES_UNKNOWN_OPCODE, hd_can_decode_cmd(&f, &d));
    f = good;
    hd_le_put_f32(&f.data[4], NAN);
    TEST_ASSERT_EQUAL_INT(HD_CAN_RES_NOT_FINITE, hd_can_decode_cmd(&f, &d));
    f = good;
    f.data[0] = HD_CMD_ADD_OUTPUT;
    hd_le_put_f32(&f.data[4], -INFINITY);
    TEST_ASSERT_EQUAL_INT(HD_CAN_RES_NOT_FINITE, hd_can_decode_cmd(&f, &d));
}

static void test_ack_and_heartbeat_layouts(void)
{
    hd_can_ack_t a = {HD_CMD_GET_PARAM, 9, HD_CAN_RES_OK, HD_PARAM_R_NM2, 0.5f, 0u};
    hal_can_frame_t f;
    hd_can_encode_ack(1, &a, &f);
    const uint8_t e[8] = {0x21, 0x09, 0x00, 0x01, 0x00, 0x00, 0x00, 0x3F}; /* 0.5f = 0x3F000000 */
    TEST_ASSERT_EQUAL_HEX32(0x01D01101u, f.id);
    TEST_ASSERT_EQUAL_MEMORY(e, f.data, 8);
    hd_can_ack_t d;
    TEST_ASSERT_EQUAL_INT(0, hd_can_decode_ack(&f, &d));
    TEST_ASSERT_EQUAL_FLOAT(0.5f, d.value);
    /* VERSION answers carry a u32, not a float */
    hd_can_ack_t v = {HD_CMD_VERSION, 1, HD_CAN_RES_OK, 2, 0.0f, 0x00010203u};
    hd_can_encode_ack(1, &v, &f);
    const uint8_t ev[8] = {0x60, 0x01, 0x00, 0x02, 0x03, 0x02, 0x01, 0x00};
    TEST_ASSERT_EQUAL_MEMORY(ev, f.data, 8);
    TEST_ASSERT_EQUAL_INT(0, hd_can_decode_ack(&f, &d));
    TEST_ASSERT_EQUAL_HEX32(0x00010203u, d.value_u32);

    hd_can_heartbeat_t h = {HD_STATE_DEGRADED, 0x020401u, 0x1234u, 2u, 4u, 6u};
    hd_can_encode_heartbeat(127, &h, &f);
    const uint8_t eh[8] = {0x02, 0x01, 0x04, 0x02, 0x34, 0x12, 0x42, 0x06};
    TEST_ASSERT_EQUAL_HEX32(0x01D0207Fu, f.id);
    TEST_ASSERT_EQUAL_MEMORY(eh, f.data, 8);
    hd_can_heartbeat_t hd;
    TEST_ASSERT_EQUAL_INT(0, hd_can_decode_heartbeat(&f, &hd));
    TEST_ASSERT_EQUAL_UINT16(0x1234u, hd.deadline_misses);
    TEST_ASSERT_EQUAL_UINT8(4u, hd.config_status);
    TEST_ASSERT_EQUAL_HEX32(0x020401u, hd.faults);
}

static void test_angle_boot_and_feedforward_layouts(void)
{
    hd_can_angle_t c = {0x89ABCDEFu, 0x12345678u, true, 9u};
    hal_can_frame_t f;
    hd_can_encode_angle(2, &c, &f);
    /* motor counts as u32; the output's low 23 bits with bit 23 = present */
    const uint8_t ec[8] = {0xEF, 0xCD, 0xAB, 0x89, 0x78, 0x56, 0xB4, 0x09};
    TEST_ASSERT_EQUAL_HEX32(0x01D00402u, f.id);
    TEST_ASSERT_EQUAL_MEMORY(ec, f.data, 8);
    hd_can_angle_t cd;
    TEST_ASSERT_EQUAL_INT(0, hd_can_decode_angle(&f, &cd));
    TEST_ASSERT_TRUE(cd.has_output);
    TEST_ASSERT_EQUAL_HEX32(0x345678u, cd.output_counts);

    hd_can_boot_t b = {HAL_RESET_WATCHDOG, true, false, 0x08001234u, 2u, 3u};
    hd_can_encode_boot(1, &b, &f);
    const uint8_t eb[8] = {0x08, 0x01, 0x34, 0x12, 0x00, 0x08, 0x02, 0x03};
    TEST_ASSERT_EQUAL_HEX32(0x01D02101u, f.id);
    TEST_ASSERT_EQUAL_MEMORY(eb, f.data, 8);

    hd_can_feedforward_t ff = {-2.5f, 7u};
    hd_can_encode_feedforward(1, &ff, &f);
    const uint8_t ef[8] = {0x00, 0x00, 0x20, 0xC0, 0x07, 0x00, 0x00, 0x00}; /* -2.5f = 0xC0200000 */
    TEST_ASSERT_EQUAL_HEX32(0x01D00101u, f.id);
    TEST_ASSERT_EQUAL_MEMORY(ef, f.data, 8);
    hd_can_feedforward_t fd;
    TEST_ASSERT_EQUAL_INT(HD_CAN_RES_OK, hd_can_decode_feedforward(&f, &fd));
    TEST_ASSERT_EQUAL_FLOAT(-2.5f, fd.torque_nm);
    hd_le_put_f32(&f.data[0], NAN);
    TEST_ASSERT_EQUAL_INT(HD_CAN_RES_NOT_FINITE, hd_can_decode_feedforward(&f, &fd));
}

static void test_identifiers_are_ours_only(void)
{
    uint8_t type = 0, node = 0;
    TEST_ASSERT_TRUE(hd_can_id_parse(0x01D0107Fu, HAL_CAN_FLAG_EXT, &type, &node));
    TEST_ASSERT_EQUAL_UINT8(HD_CAN_FRAME_CMD, type);
    TEST_ASSERT_EQUAL_UINT8(127, node);
    TEST_ASSERT_FALSE(hd_can_id_parse(0x01D0107Fu, 0u, &type, &node));      /* 11-bit flag */
    TEST_ASSERT_FALSE(hd_can_id_parse(0x01D01000u, HAL_CAN_FLAG_EXT, &type, &node)); /* node 0 */
    TEST_ASSERT_FALSE(hd_can_id_parse(0x01D01080u, HAL_CAN_FLAG_EXT, &type, &node)); /* 128 */
    TEST_ASSERT_FALSE(hd_can_id_parse(0x01D11001u, HAL_CAN_FLAG_EXT, &type, &node)); /* prefix */
    TEST_ASSERT_FALSE(hd_can_id_parse(0x601u, 0u, &type, &node));            /* CANopen SDO */
}

static void test_candump_line_format(void)
{
    hal_can_frame_t f = {0};
    f.id = 0x101;
    f.len = 3;
    f.data[0] = 0xDE;
    f.data[1] = 0xAD;
    f.data[2] = 0x01;
    char buf[128];
    int n = hal_candump_format(&f, 12345678ull, "vcan0", buf, sizeof buf);
    TEST_ASSERT_EQUAL_STRING("(0000000012.345678) vcan0 101#DEAD01\n", buf);
    TEST_ASSERT_EQUAL_INT((int)strlen(buf), n);
    f.flags = HAL_CAN_FLAG_EXT;
    f.id = 0x1ABCDEF;
    hal_candump_format(&f, 0, "can0", buf, sizeof buf);
    TEST_ASSERT_EQUAL_STRING("(0000000000.000000) can0 01ABCDEF#DEAD01\n", buf);
    f.flags = HAL_CAN_FLAG_RTR;
    f.id = 0x7FF;
    hal_candump_format(&f, 0, "can0", buf, sizeof buf);
    TEST_ASSERT_EQUAL_STRING("(0000000000.000000) can0 7FF#R\n", buf);
    f.flags = HAL_CAN_FLAG_FD;
    f.id = 0x10;
    hal_candump_format(&f, 0, "can0", buf, sizeof buf);
    TEST_ASSERT_EQUAL_STRING("(0000000000.000000) can0 010##0DEAD01\n", buf);
    TEST_ASSERT_EQUAL_INT(-1, hal_candump_format(&f, 0, "can0", buf, 10)); /* too small */
}

int main(int argc, char **argv)
{
    if (UnityParseOptions(argc, argv) != 0) {
        return 1;
    }
    UNITY_BEGIN();
    RUN_TEST(test_telem_bytes_match_the_documented_layout);
    RUN_TEST(test_telem_saturates_and_marks_not_available);
    RUN_TEST(test_command_bytes_match_the_documented_example);
    RUN_TEST(test_command_argument_bytes);
    RUN_TEST(test_command_round_trips);
    RUN_TEST(test_malformed_commands_are_classified);
    RUN_TEST(test_ack_and_heartbeat_layouts);
    RUN_TEST(test_angle_boot_and_feedforward_layouts);
    RUN_TEST(test_identifiers_are_ours_only);
    RUN_TEST(test_candump_line_format);
    return UNITY_END();
}
