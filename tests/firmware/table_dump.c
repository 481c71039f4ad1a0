/* Prints what the C side makes of hd_params.def and hd_protocol.def, and a
 * few frames from the C encoders, one JSON object per line, for
 * test_protocol_tables.py to compare with the Python side and the DBC. */
#include <math.h>
#include <stdio.h>
#include <string.h>

#include "hd_can_proto.h"
#include "hd_fw.h"
#include "hd_params.h"

static void frame(const char *what, const hal_can_frame_t *f)
{
    printf("{\"frame\": \"%s\", \"id\": %lu, \"ext\": %d, \"data\": \"", what, (unsigned long)f->id,
           (f->flags & HAL_CAN_FLAG_EXT) != 0u);
    for (unsigned i = 0; i < f->len; i++) {
        printf("%02x", f->data[i]);
    }
    printf("\"}\n");
}

int main(void)
{
    hd_fw_config_t defaults;
    hd_fw_config_default(&defaults);
    for (size_t i = 0; i < hd_param_count(); i++) {
        const hd_param_info_t *p = hd_param_at(i);
        char dflt[32] = "null"; /* LIB: the library's default */
        if (!isnan(p->dflt)) {
            snprintf(dflt, sizeof dflt, "%.17g", (double)p->dflt);
        }
        printf("{\"param\": %u, \"name\": \"%s\", \"key\": \"%s\", \"type\": %u, \"flags\": %u, "
               "\"lo\": %.17g, \"hi\": %.17g, \"default\": %s, \"value\": %.17g}\n",
               p->id, p->name, p->key, p->type, p->flags, (double)p->lo, (double)p->hi, dflt,
               (double)hd_param_get(p, &defaults));
    }
    printf("{\"param_table_crc\": %lu}\n", (unsigned long)hd_param_table_crc());
    /* control/'s limits that the SETPOINT and GAINS rows document as ranges */
    printf("{\"ctrl_kp_max\": %.17g, \"ctrl_kd_max\": %.17g, \"ctrl_modes\": %d}\n",
           (double)HD_CTRL_KP_MAX_NM_RAD, (double)HD_CTRL_KD_MAX_NM_S_RAD, (int)HD_CTRL_MODE_COUNT);
    for (int c = 0; c < 256; c++) {
        if (strcmp(hd_can_opcode_str(c), "UNKNOWN_OPCODE") != 0) {
            printf("{\"opcode\": %d, \"name\": \"%s\"}\n", c, hd_can_opcode_str(c));
        }
        if (strcmp(hd_can_result_str(c), "UNKNOWN_RESULT") != 0) {
            printf("{\"result\": %d, \"name\": \"%s\"}\n", c, hd_can_result_str(c));
        }
    }
    for (unsigned b = 0; b < HD_FAULT_COUNT; b++) {
        printf("{\"fault\": %u, \"name\": \"%s\"}\n", b, hd_can_fault_str(b));
    }
    /* Frames with known contents (the test decodes them with the DBC). */
    hal_can_frame_t a, b;
    hd_can_telem_t t = {12.34f, -1.5f, 0.25f, true, -156.0f, 0x018410u, 0x05u, 0x7Fu};
    hd_can_encode_telem(3, &t, &a, &b);
    frame("TELEM_A", &a);
    frame("TELEM_B", &b);
    hd_can_angle_t ang = {0x89ABCDEFu, 0x345678u, true, 9u};
    hd_can_encode_angle(3, &ang, &a);
    frame("TELEM_C", &a);
    hd_can_heartbeat_t h = {HD_STATE_DEGRADED, 0x020401u, 0x1234u, 2u, 4u, 6u};
    hd_can_encode_heartbeat(3, &h, &a);
    frame("HEARTBEAT", &a);
    hd_can_boot_t bt = {HAL_RESET_WATCHDOG, true, false, 0x08001234u, 2u, 3u};
    hd_can_encode_boot(3, &bt, &a);
    frame("BOOT", &a);
    hd_can_ack_t ack = {HD_CMD_GET_PARAM, 9, HD_CAN_RES_OK, HD_PARAM_R_NM2, 0.5f, 0u};
    hd_can_encode_ack(3, &ack, &a);
    frame("ACK_FLOAT", &a);
    hd_can_ack_t ver = {HD_CMD_VERSION, 1, HD_CAN_RES_OK, HD_INFO_FIRMWARE_VERSION, 0.0f, 0x00010203u};
    hd_can_encode_ack(3, &ver, &a);
    frame("ACK_U32", &a);
    hd_can_cmd_t c = {HD_CMD_SET_PARAM, 7, {.set_param = {HD_PARAM_GEAR_RATIO, 121.0f}}};
    hd_can_encode_cmd(3, &c, &a);
    frame("CMD", &a);
    /* One command of each argument type (U, UQ, F32, F32_ANY, u32). */
    hd_can_cmd_t cf = {HD_CMD_ADD_FIXED, 8, {.add_fixed = {123.45f, 2.5f}}};
    hd_can_encode_cmd(3, &cf, &a);
    frame("CMD_ADD_FIXED", &a);
    hd_can_cmd_t cg = {HD_CMD_BLOCK_GET, 9, {.block_get = {5u, HD_BLOCK_FIELD_Q_NM2}}};
    hd_can_encode_cmd(3, &cg, &a);
    frame("CMD_BLOCK_GET", &a);
    hd_can_cmd_t cp = {HD_CMD_PROFILE_PUT, 10, {.profile_put = {0x13u, 2u, -1.5f}}};
    hd_can_encode_cmd(3, &cp, &a);
    frame("CMD_PROFILE_PUT", &a);
    hd_can_cmd_t cc = {HD_CMD_CALIB_SAVE, 11, {.calib_save = {1700000000u}}};
    hd_can_encode_cmd(3, &cc, &a);
    frame("CMD_CALIB_SAVE", &a);
    hd_can_feedforward_t ff = {-2.5f, 7u};
    hd_can_encode_feedforward(3, &ff, &a);
    frame("FEEDFORWARD", &a);
    hd_can_setpoint_t sp = {3u, 200u, -12.5f, 1.25f, -0.75f};
    hd_can_encode_setpoint(3, &sp, &a);
    frame("SETPOINT", &a);
    hd_can_gains_t g = {150.0f, 2.5f};
    hd_can_encode_gains(3, &g, &a);
    frame("GAINS", &a);
    hd_can_ctrl_state_t cs = {2u, 1u, 0x28u, -3.5f, 1.234f, 17u, 0x03u};
    hd_can_encode_ctrl_state(3, &cs, &a);
    frame("CTRL_STATE", &a);
    return 0;
}
