/* The ODrive CAN Simple frames of hal/odrive as JSON lines, for
 * test_odrive_frames.py to decode with the odrive-can package's DBC:
 *   odrive_dump                 the encoder's frames for node 5
 *   odrive_dump ID HEX          decodes a heartbeat: {"axis_error": .., ...}
 * (exit 2 when the frame is refused). */
#include <stdio.h>
#include <stdlib.h>
#include <string.h>

#include "hal_odrive.h"

static void dump(const char *what, const hal_can_frame_t *f)
{
    printf("{\"frame\": \"%s\", \"id\": %lu, \"ext\": %d, \"data\": \"", what, (unsigned long)f->id,
           (f->flags & HAL_CAN_FLAG_EXT) != 0u);
    for (unsigned i = 0; i < f->len; i++) {
        printf("%02x", f->data[i]);
    }
    printf("\"}\n");
}

int main(int argc, char **argv)
{
    hal_can_frame_t f;
    if (argc == 3) {
        memset(&f, 0, sizeof f);
        f.id = (uint32_t)strtoul(argv[1], NULL, 0);
        const size_t n = strlen(argv[2]) / 2u;
        f.len = (uint8_t)(n > 8u ? 8u : n);
        for (unsigned i = 0; i < f.len; i++) {
            unsigned b = 0;
            sscanf(&argv[2][2u * i], "%2x", &b);
            f.data[i] = (uint8_t)b;
        }
        hal_odrive_heartbeat_t hb;
        if (hal_odrive_decode_heartbeat(&f, &hb) != HAL_OK) {
            return 2;
        }
        printf("{\"axis_error\": %lu, \"axis_state\": %u, \"procedure_result\": %u, "
               "\"trajectory_done\": %d}\n",
               (unsigned long)hb.axis_error, hb.axis_state, hb.procedure_result, hb.trajectory_done);
        return 0;
    }
    hal_odrive_encode_set_axis_state(5, HAL_ODRIVE_AXIS_STATE_CLOSED_LOOP, &f);
    dump("Set_Axis_State", &f);
    hal_odrive_encode_set_controller_mode(5, HAL_ODRIVE_CONTROL_MODE_TORQUE,
                                          HAL_ODRIVE_INPUT_MODE_PASSTHROUGH, &f);
    dump("Set_Controller_Mode", &f);
    hal_odrive_encode_set_input_torque(5, -0.3125f, &f);
    dump("Set_Input_Torque", &f);
    hal_odrive_encode_clear_errors(5, &f);
    dump("Clear_Errors", &f);
    return 0;
}
