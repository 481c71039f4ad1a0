/* Fuzz: CAN frames into the firmware (hd_can_decode_* and
 * hd_fw_handle_frame), interleaved with ISR ticks and background work.
 *
 * Input: records of 12 bytes: [0] id selector (bit 7: this node's command
 * id, else the 11-bit id from bytes 0..1), [2] flags, [3] length (mod 65),
 * [4..11] data; every record with bit 6 of byte 0 set is followed by one
 * tick whose ADC counts come from its data.
 * Properties: nothing crashes; the running configuration always passes
 * hd_fw_config_check; the calibration in RAM is finite with gain > 0;
 * every frame on the command id is answered by exactly one ACK (or queued
 * for background work, which then answers); decoders return documented
 * codes. */
#include <math.h>
#include <string.h>

#include "fuzz.h"
#include "hal_mock.h"
#include "hd_can_proto.h"
#include "hd_fw.h"

static hal_mock_t mock;
static hal_t hal;
static hd_fw_t fw;

static unsigned acks_sent(uint8_t node)
{
    unsigned n = 0;
    for (uint32_t i = 0; i < hal_mock_tx_count(&mock); i++) {
        n += hal_mock_tx(&mock, i)->id == HD_CAN_ID_ACK + node;
    }
    return n;
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
        uint8_t node = fw.cfg.node_id;
        f.id = (r[0] & 0x80u) ? HD_CAN_ID_CMD + node : (uint32_t)((r[0] | r[1] << 8) & 0x7FF);
        f.flags = r[2] & 0x0Fu;
        f.len = (uint8_t)(r[3] % (HAL_CAN_MAX_DATA + 1u));
        memcpy(f.data, &r[4], 8);

        hd_can_cmd_t cmd;
        int res = hd_can_decode_cmd(&f, &cmd);
        FUZZ_CHECK(res >= HD_CAN_RES_OK && res <= HD_CAN_RES_NO_DATA);
        FUZZ_CHECK(hd_can_result_str(res) != NULL);
        hd_can_ack_t ack;
        hd_can_heartbeat_t hb;
        hd_can_telem_t tm;
        (void)hd_can_decode_ack(&f, &ack);
        (void)hd_can_decode_heartbeat(&f, &hb);
        (void)hd_can_decode_telem(&f, &f, &tm);

        bool for_us = f.id == HD_CAN_ID_CMD + node && (f.flags & HAL_CAN_FLAG_ERR) == 0u;
        uint8_t pending_before = fw.nvm_pending;
        unsigned acks_before = acks_sent(node);
        uint32_t stored_before = hal_mock_tx_count(&mock);
        hd_fw_handle_frame(&fw, &f);
        if (stored_before < HAL_MOCK_TX_CAP - 2u) {
            unsigned acks = acks_sent(node);
            bool queued = pending_before == 0u && fw.nvm_pending != 0u;
            FUZZ_CHECK(acks == acks_before + ((for_us && !queued) ? 1u : 0u));
        }
        FUZZ_CHECK(hd_fw_config_check(&fw.cfg) == HD_FW_OK);
        FUZZ_CHECK(isfinite(fw.calib.gain_nm_per_v) && fw.calib.gain_nm_per_v > 0.0f);
        FUZZ_CHECK(isfinite(fw.calib.offset_v));

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
