/*
 * hd_lockstep: the per-tick exchange between a firmware image and a plant
 * on the host (issue 23, docs/results/target.md "Closed loop"), and the same
 * exchange done in one host process for the reference.  One record each
 * way per tick, little-endian:
 *
 *   plant -> firmware, before tick k (24 bytes):
 *     i32 bridge_counts, u32 flags (HD_LS_*), u32 motor_counts,
 *     u32 output_counts, u32 setpoint mode | seq << 8 (mode HD_LS_END: no
 *     more ticks), f32 setpoint torque (N m, float bits)
 *   firmware -> plant, after tick k (28 bytes):
 *     u32 tick, u32 mode run | drive enabled << 8, f32 current command (A),
 *     f32 torque reference (N m), f32 filtered torque (N m), u32 faults,
 *     u32 limits (HD_CTRL_LIM_*)
 *
 * The firmware takes the sample through hal_mock (sensors, CAN receive)
 * and the setpoint as the SETPOINT frame a host would send; its drive is a
 * recording actuator whose last command goes back.  Header-only, no heap,
 * no libm: it builds for the image and for the host.
 */
#ifndef HD_LOCKSTEP_H
#define HD_LOCKSTEP_H

#include <stdbool.h>
#include <stdint.h>
#include <string.h>

#include "hal_mock.h"
#include "hd_fw.h"

#define HD_LS_SAMPLE_BYTES 24u
#define HD_LS_COMMAND_BYTES 28u
#define HD_LS_SATURATED 0x01u
#define HD_LS_HAS_OUTPUT 0x02u
#define HD_LS_ENC_FAULT 0x04u
#define HD_LS_END 0xFFu

typedef struct {
    hal_mock_sample_t sample;
    uint8_t mode;
    uint8_t seq;
    float torque_nm;
} hd_ls_sample_t;

/* The recording drive. */
typedef struct {
    bool enabled;
    float current_a;
} hd_ls_drive_t;

static inline uint32_t hd_ls_get32(const uint8_t *p)
{
    return (uint32_t)p[0] | (uint32_t)p[1] << 8 | (uint32_t)p[2] << 16 | (uint32_t)p[3] << 24;
}

static inline void hd_ls_put32(uint8_t *p, uint32_t v)
{
    p[0] = (uint8_t)v;
    p[1] = (uint8_t)(v >> 8);
    p[2] = (uint8_t)(v >> 16);
    p[3] = (uint8_t)(v >> 24);
}

static inline uint32_t hd_ls_bits(float f)
{
    uint32_t u;
    memcpy(&u, &f, sizeof u);
    return u;
}

static inline float hd_ls_float(uint32_t u)
{
    float f;
    memcpy(&f, &u, sizeof f);
    return f;
}

static inline void hd_ls_pack_sample(const hd_ls_sample_t *s, uint8_t out[HD_LS_SAMPLE_BYTES])
{
    const hal_mock_sample_t *m = &s->sample;
    hd_ls_put32(&out[0], (uint32_t)m->adc.bridge_counts);
    hd_ls_put32(&out[4], (m->adc.saturated ? HD_LS_SATURATED : 0u) |
                             (m->enc.has_output ? HD_LS_HAS_OUTPUT : 0u) |
                             (m->enc.fault ? HD_LS_ENC_FAULT : 0u));
    hd_ls_put32(&out[8], m->enc.motor_counts);
    hd_ls_put32(&out[12], m->enc.output_counts);
    hd_ls_put32(&out[16], (uint32_t)s->mode | (uint32_t)s->seq << 8);
    hd_ls_put32(&out[20], hd_ls_bits(s->torque_nm));
}

static inline void hd_ls_unpack_sample(const uint8_t in[HD_LS_SAMPLE_BYTES], hd_ls_sample_t *s)
{
    memset(s, 0, sizeof *s);
    const uint32_t flags = hd_ls_get32(&in[4]);
    s->sample.adc.bridge_counts = (int32_t)hd_ls_get32(&in[0]);
    s->sample.adc.saturated = (flags & HD_LS_SATURATED) != 0u;
    s->sample.enc.has_output = (flags & HD_LS_HAS_OUTPUT) != 0u;
    s->sample.enc.fault = (flags & HD_LS_ENC_FAULT) != 0u;
    s->sample.enc.motor_counts = hd_ls_get32(&in[8]);
    s->sample.enc.output_counts = hd_ls_get32(&in[12]);
    const uint32_t sp = hd_ls_get32(&in[16]);
    s->mode = (uint8_t)sp;
    s->seq = (uint8_t)(sp >> 8);
    s->torque_nm = hd_ls_float(hd_ls_get32(&in[20]));
}

/* Queues tick k's sample and setpoint frame for the firmware; sets the
 * mock's clock to the tick's time. */
static inline int hd_ls_feed(hal_mock_t *mock, const hd_fw_t *fw, const hd_ls_sample_t *s,
                             uint32_t tick)
{
    const hd_can_setpoint_t sp = {s->mode, s->seq, s->torque_nm, 0.0f, 0.0f};
    hal_can_frame_t f;
    hd_can_encode_setpoint(hd_fw_config(fw)->node_id, &sp, &f);
    mock->now_us = (uint64_t)tick * HD_FW_TS_US;
    if (hal_mock_push_sample(mock, &s->sample) != HAL_OK) {
        return -1;
    }
    return hal_mock_push_rx(mock, &f) == HAL_OK ? 0 : -1;
}

/* The record of tick k after hd_fw_isr. */
static inline void hd_ls_pack_command(const hd_fw_t *fw, const hd_ls_drive_t *d, uint32_t tick,
                                      uint8_t out[HD_LS_COMMAND_BYTES])
{
    const hd_ctrl_output_t *o = &fw->control.out;
    const hd_fw_sample_t *s = hd_fw_last_sample(fw);
    hd_ls_put32(&out[0], tick);
    hd_ls_put32(&out[4], (uint32_t)o->mode | (d->enabled ? 1u : 0u) << 8);
    hd_ls_put32(&out[8], hd_ls_bits(d->current_a));
    hd_ls_put32(&out[12], hd_ls_bits(o->torque_ref_nm));
    hd_ls_put32(&out[16], hd_ls_bits(s->torque_filtered_nm));
    hd_ls_put32(&out[20], s->faults);
    hd_ls_put32(&out[24], o->limits);
}

static inline int hd_ls_drive_enable(void *ctx, bool on)
{
    hd_ls_drive_t *d = (hd_ls_drive_t *)ctx;
    d->enabled = on;
    if (!on) {
        d->current_a = 0.0f;
    }
    return HAL_OK;
}

static inline int hd_ls_drive_command(void *ctx, float current_a)
{
    ((hd_ls_drive_t *)ctx)->current_a = current_a;
    return HAL_OK;
}

/* The firmware's drive: hal->actuator records into d. */
static inline void hd_ls_bind_drive(hd_ls_drive_t *d, hal_t *hal)
{
    memset(d, 0, sizeof *d);
    hal->actuator = (hal_actuator_t){d, hd_ls_drive_enable, hd_ls_drive_command, NULL};
}

#endif /* HD_LOCKSTEP_H */
