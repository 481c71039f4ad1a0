/* hd_fw_ff: the feed-forward latch stage (hd_fw_stages.h).
 *
 * Contract: hd_fw_ff_age once per tick before the frames are taken,
 * hd_fw_ff_take for each FEEDFORWARD frame of ours, hd_fw_ff once per tick
 * after the sensors.  With feedforward_timeout_ms = 0 no feed-forward is
 * expected: frames are ignored and T_ff is 0.  A malformed, non-finite or
 * out-of-range frame is never latched (HD_FAULT_FF_REJECTED); a repeated
 * sequence number is not new data.  A value older than the timeout is
 * stale: HD_FAULT_FF_STALE and hd_slow_feedforward_ramp_nm's fallback
 * (docs/design/slow-torque.md, "Feed-forward"). */
#include "hd_fw.h"
#include "hd_fw_internal.h"

void hd_fw_ff_age(hd_fw_ff_t *k)
{
    if (k->age_ticks < UINT32_MAX) {
        k->age_ticks++; /* the latched feed-forward is one tick older */
    }
}

uint32_t hd_fw_ff_take(hd_fw_ff_t *k, const hd_fw_config_t *c, const hal_can_frame_t *f,
                       uint32_t *accepted)
{
    if (c->feedforward_timeout_ms == 0u) {
        return 0u;
    }
    hd_can_feedforward_t ff;
    if (hd_can_decode_feedforward(f, &ff) != HD_CAN_RES_OK || ff.torque_nm > c->torque_limit_nm ||
        ff.torque_nm < -c->torque_limit_nm) {
        return HD_FAULT_FF_REJECTED;
    }
    if (k->have && ff.seq == k->seq) {
        return 0u;
    }
    k->have = true;
    k->seq = ff.seq;
    k->nm = ff.torque_nm;
    k->age_ticks = 0u;
    (*accepted)++;
    return 0u;
}

uint32_t hd_fw_ff(hd_fw_ff_t *k, const hd_fw_config_t *c, hd_fw_sample_t *s)
{
    s->feedforward_nm = 0.0f;
    if (c->feedforward_timeout_ms == 0u) {
        return 0u;
    }
    if (k->have && k->age_ticks <= c->feedforward_timeout_ms) {
        k->stale_ticks = 0u;
        s->feedforward_nm = k->nm;
        return 0u;
    }
    if (k->stale_ticks < UINT32_MAX) {
        k->stale_ticks++;
    }
    /* nm is the last fresh value: a frame makes it fresh again */
    s->feedforward_nm = hd_slow_feedforward_ramp_nm(k->nm, k->stale_ticks, c->feedforward_ramp_ms);
    return HD_FAULT_FF_STALE;
}
