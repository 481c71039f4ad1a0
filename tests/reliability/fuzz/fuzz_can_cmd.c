/* Fuzz: CAN frames into the firmware (hd_can_decode_* and
 * hd_fw_handle_frame), interleaved with ISR ticks and background work.
 *
 * Input: records of 12 bytes: [0] id selector (bit 7: this node's command
 * id, else a 29-bit id of our prefix with type and node from bytes 0..1, or
 * (bit 5) an 11-bit id), [2] flags, [3] length (mod 65), [4..11] data;
 * every record with bit 6 of byte 0 set is followed by one tick whose ADC
 * counts come from its data.
 * Properties: nothing crashes; the running configuration always passes
 * hd_fw_config_check; the calibration in RAM is finite with gain > 0;
 * every frame handed to hd_fw_handle_frame on the command id is answered
 * by exactly one ACK (a PROFILE_SAVE later, when its snapshot is saved);
 * decoders return documented codes. */
#include <math.h>
#include <string.h>

#include "fuzz.h"
#include "hal_mock.h"
#include "hd_can_proto.h"
#include "hd_fw.h"
#include "hd_fw_internal.h"

static hal_mock_t mock;
static hal_t hal;
static hd_fw_t fw;

static uint32_t acks_queued(void)
{
    return fw.ack_queue.head;
}

int LLVMFuzzerTestOneInput(const uint8_t *data, size_t size)
{
    hal_mock_init(&mock);
    hal_mock_bind(&mock, &hal);
    hd_fw_config_t cfg;
    hd_fw_config_default(&cfg);
    FUZZ_CHECK(hd_fw_init(&fw, &hal, &cfg) == HD_FW_OK);
    uint32_t motor = 0;
    for (size_t off = 0; off + 12u <= size && off < 12u * 64u; off += 12u) {
        const uint8_t *r = &data[off];
        hal_can_frame_t f;
        memset(&f, 0, sizeof f);
        uint8_t node = hd_fw_config(&fw)->node_id;
        f.flags = r[2] & 0x0Fu;
        if (r[0] & 0x80u) {
            f.id = hd_can_id(HD_CAN_FRAME_CMD, node);
            f.flags |= HAL_CAN_FLAG_EXT;
        } else if (r[0] & 0x20u) {
            f.id = (uint32_t)((r[0] | r[1] << 8) & 0x7FF);
        } else {
            f.id = HD_CAN_ID_PREFIX | ((uint32_t)r[1] << 8) | (r[0] & 0x1Fu);
        }
        f.len = (uint8_t)(r[3] % (HAL_CAN_MAX_DATA + 1u));
        memcpy(f.data, &r[4], 8);

        hd_can_cmd_t cmd;
        int res = hd_can_decode_cmd(&f, &cmd);
        FUZZ_CHECK(res >= HD_CAN_RES_OK && res <= HD_CAN_RES_UNSUPPORTED);
        FUZZ_CHECK(hd_can_result_str(res) != NULL);
        hd_can_ack_t ack;
        hd_can_heartbeat_t hb;
        hd_can_telem_t tm;
        (void)hd_can_decode_ack(&f, &ack);
        (void)hd_can_decode_heartbeat(&f, &hb);
        (void)hd_can_decode_telem(&f, &f, &tm);
        hd_can_angle_t an;
        hd_can_boot_t bt;
        hd_can_feedforward_t ff;
        (void)hd_can_decode_angle(&f, &an);
        (void)hd_can_decode_boot(&f, &bt);
        (void)hd_can_decode_feedforward(&f, &ff);

        uint8_t type = 0, to = 0;
        bool for_us = (f.flags & HAL_CAN_FLAG_ERR) == 0u &&
                      hd_can_id_parse(f.id, f.flags, &type, &to) && to == node &&
                      type == HD_CAN_FRAME_CMD;
        if (!hd_fw_queue_full(&fw.ack_queue)) {
            uint32_t before = acks_queued();
            bool saving = fw.bg.save_pending;
            hd_fw_handle_frame(&fw, &f);
            /* A PROFILE_SAVE is answered once the tick's snapshot is saved. */
            bool deferred = !saving && fw.bg.save_pending;
            FUZZ_CHECK(acks_queued() == before + ((for_us && !deferred) ? 1u : 0u));
        }
        const hd_fw_config_t *c = hd_fw_config(&fw);
        FUZZ_CHECK(hd_fw_config_check(c, NULL) == HD_FW_OK);
        FUZZ_CHECK(isfinite(c->calib_gain_nm_per_v) && c->calib_gain_nm_per_v > 0.0f);
        FUZZ_CHECK(isfinite(c->calib_offset_v));
        (void)hal_mock_push_rx(&mock, &f); /* and the same frame through the tick */

        if (r[0] & 0x40u) {
            int32_t counts;
            memcpy(&counts, &r[4], 4);
            motor += r[8];
            FUZZ_CHECK(hal_mock_push(&mock, counts, motor) == 0);
            uint32_t ticks = fw.counters.ticks;
            hd_fw_isr(&fw);
            FUZZ_CHECK(fw.counters.ticks == ticks + 1u);
            const hd_fw_sample_t *s = hd_fw_last_sample(&fw);
            FUZZ_CHECK(!s->valid || isfinite(s->torque_filtered_nm));
            FUZZ_CHECK(isfinite(s->ripple_nm));
        }
        (void)hd_fw_background(&fw);
    }
    return 0;
}
