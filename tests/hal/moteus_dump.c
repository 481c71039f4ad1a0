/* hal/moteus's register bytes for test_moteus_frames.py (the moteus
 * package's encoder and parser are the reference):
 *   moteus_dump                  {"torque_query": HEX, "torque": HEX, "stop": HEX, "id": ..}
 *   moteus_dump HEX              the reply parsed: {"mode": .., "torque": .., ...}
 * (exit 2 when the reply is refused). */
#include <stdio.h>
#include <string.h>

#include "hal_moteus.h"

static void hex(const char *key, const uint8_t *b, size_t n, const char *sep)
{
    printf("\"%s\": \"", key);
    for (size_t i = 0; i < n; i++) {
        printf("%02x", b[i]);
    }
    printf("\"%s", sep);
}

int main(int argc, char **argv)
{
    uint8_t b[64];
    if (argc == 2) {
        const size_t n = strlen(argv[1]) / 2u > sizeof b ? sizeof b : strlen(argv[1]) / 2u;
        for (size_t i = 0; i < n; i++) {
            unsigned v = 0;
            sscanf(&argv[1][2u * i], "%2x", &v);
            b[i] = (uint8_t)v;
        }
        hal_moteus_reply_t r = {0};
        if (hal_moteus_parse_reply(b, n, &r) != HAL_OK) {
            return 2;
        }
        printf("{\"mode\": %u, \"position\": %.9g, \"velocity\": %.9g, \"torque\": %.9g, "
               "\"voltage\": %.9g, \"temperature\": %.9g, \"fault\": %lu}\n",
               r.mode, (double)r.position_rev, (double)r.velocity_rev_s, (double)r.torque_nm,
               (double)r.voltage_v, (double)r.temperature_c, (unsigned long)r.fault);
        return 0;
    }
    printf("{");
    size_t n = hal_moteus_encode_torque(0.25f, true, b, sizeof b);
    hex("torque_query", b, n, ", ");
    n = hal_moteus_encode_torque(-1.5f, false, b, sizeof b);
    hex("torque", b, n, ", ");
    n = hal_moteus_encode_stop(b, sizeof b);
    hex("stop", b, n, ", ");
    hal_can_frame_t f;
    n = hal_moteus_encode_torque(0.25f, true, b, sizeof b);
    (void)hal_moteus_frame(3u, 0u, true, b, n, &f);
    printf("\"id\": %lu, \"len\": %u, \"fd\": %d}\n", (unsigned long)f.id, f.len,
           (f.flags & HAL_CAN_FLAG_FD) != 0u);
    return 0;
}
