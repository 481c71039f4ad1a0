/* The firmware on the mock HAL, for the firmware tests: a calibration
 * record in NVM, ticks with given ADC counts and motor steps, commands sent
 * the way a bus delivers them (the tick queues, the background executes,
 * the next tick sends the ACK), and lookups in the transmit log. */
#ifndef FW_RIG_H
#define FW_RIG_H

#include <string.h>

#include "hal_mock.h"
#include "hd_calib_record.h"
#include "hd_fw.h"
#include "unity.h"

#define GAIN 6.6
#define OFFSET_V 0.1
#define VPC (10.0 / 32768.0)
#define CPR 4096u
#define TEST_PI 3.14159265358979323846

static hal_mock_t mock;
static hal_t hal;
static hd_fw_t fw;
static hd_fw_config_t cfg;
static uint32_t motor = 0;
static uint8_t store_work[HD_STORE_IMAGE_MAX];

static inline hd_store_io_t storage(void)
{
    return hd_fw_store_io(&hal, store_work, sizeof store_work);
}

static inline void store_calibration(float gain, float offset)
{
    hd_calib_record_t rec;
    hd_calib_record_default(&rec);
    rec.gain_nm_per_v = gain;
    rec.offset_v = offset;
    hd_store_io_t s = storage();
    TEST_ASSERT_EQUAL_INT(HD_RECORD_OK, hd_calib_store_save(&s, &rec));
}

static inline void rig_reset(void)
{
    hal_mock_init(&mock);
    hal_mock_bind(&mock, &hal);
    hd_fw_config_default(&cfg);
    cfg.motor_cpr = CPR;
    cfg.adc_volts_per_count = (float)VPC;
    cfg.filter_enabled = 0; /* raw = filtered: exact expectations */
    store_calibration((float)GAIN, (float)OFFSET_V);
    motor = 0;
}

static inline void init_fw(void)
{
    TEST_ASSERT_EQUAL_INT(HD_FW_OK, hd_fw_init(&fw, &hal, &cfg));
}

static inline const hd_fw_config_t *live_cfg(void)
{
    return hd_fw_config(&fw);
}

static inline hd_pipeline_t *live_pipe(void)
{
    return &fw.pipe[fw.live_pipe & 1u];
}

/* Runs n ticks with constant counts and a motor moving step counts per
 * tick; the background runs after every tick, as a main loop would. */
static inline void run(unsigned n, int32_t counts, uint32_t step)
{
    for (unsigned i = 0; i < n; i++) {
        motor += step;
        TEST_ASSERT_EQUAL_INT(0, hal_mock_push(&mock, counts, motor));
        hd_fw_isr(&fw);
        hd_fw_background(&fw);
    }
}

/* Identifier of a frame type for this node (or another one). */
static inline uint32_t id_of(hd_can_frame_type_t type, uint8_t node)
{
    return hd_can_id(type, node);
}

static inline unsigned count_id(uint32_t id)
{
    unsigned n = 0;
    for (uint32_t i = 0; i < hal_mock_tx_count(&mock); i++) {
        n += hal_mock_tx(&mock, i)->id == id;
    }
    return n;
}

static inline const hal_can_frame_t *last_id(uint32_t id)
{
    const hal_can_frame_t *f = NULL;
    for (uint32_t i = 0; i < hal_mock_tx_count(&mock); i++) {
        if (hal_mock_tx(&mock, i)->id == id) {
            f = hal_mock_tx(&mock, i);
        }
    }
    return f;
}

static inline int16_t i16_at(const hal_can_frame_t *f, unsigned byte)
{
    return (int16_t)(uint16_t)(f->data[byte] | (f->data[byte + 1] << 8));
}

/* TELEM_B faults of the last telemetry frame. */
static inline uint32_t last_faults(void)
{
    hd_can_telem_t t;
    const hal_can_frame_t *b = last_id(id_of(HD_CAN_FRAME_TELEM_B, live_cfg()->node_id));
    TEST_ASSERT_NOT_NULL(b);
    const hal_can_frame_t *a = last_id(id_of(HD_CAN_FRAME_TELEM_A, live_cfg()->node_id));
    TEST_ASSERT_EQUAL_INT(0, hd_can_decode_telem(a, b, &t));
    return t.faults;
}

/* Sends one command frame and returns its ACK (0xEE everywhere if none came). */
static inline hd_can_ack_t send_frame(const hal_can_frame_t *f)
{
    uint8_t node = live_cfg()->node_id;
    uint32_t before = hal_mock_tx_count(&mock);
    hal_mock_push_rx(&mock, f);
    run(2, 1000, 1); /* tick: queued; background: executed; tick: ACK out */
    hd_can_ack_t a;
    memset(&a, 0xEE, sizeof a);
    for (uint32_t i = before; i < hal_mock_tx_count(&mock); i++) {
        const hal_can_frame_t *t = hal_mock_tx(&mock, i);
        if (t->id == id_of(HD_CAN_FRAME_ACK, node)) {
            hd_can_decode_ack(t, &a);
        }
    }
    return a;
}

static inline hd_can_ack_t send_cmd(const hd_can_cmd_t *c)
{
    hal_can_frame_t f;
    hd_can_encode_cmd(live_cfg()->node_id, c, &f);
    return send_frame(&f);
}

static inline hd_can_ack_t set_param(int id, float v)
{
    hd_can_cmd_t c = {0};
    c.opcode = HD_CMD_SET_PARAM;
    c.token = 0x33;
    c.arg.set_param.id = (uint8_t)id;
    c.arg.set_param.value = v;
    return send_cmd(&c);
}

/* A command whose one argument is the u8 at byte 2 (docs/reference/protocol.md), or
 * none: the byte is written as it is, whatever the opcode. */
static inline hd_can_ack_t simple_cmd(uint8_t opcode, uint8_t arg)
{
    hd_can_cmd_t c = {0};
    c.opcode = opcode;
    hal_can_frame_t f;
    hd_can_encode_cmd(live_cfg()->node_id, &c, &f);
    f.data[2] = arg;
    return send_frame(&f);
}

#endif /* FW_RIG_H */
