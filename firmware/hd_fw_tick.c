/* hd_fw_tick: the 1 kHz tick, hd_fw_isr.  Read hd_fw_isr at the bottom
 * first: a table of contents of stage calls (hd_fw_stages.h); the steps
 * that belong to no stage (deadline, requests, receive, faults) are the
 * functions above it. */
#include "hd_fw.h"
#include "hd_fw_internal.h"

/* ---------------------------------------------------------------- timing */

void hd_fw_note_deadline_miss(hd_fw_t *fw, uint32_t missed_ticks)
{
    if (missed_ticks == 0u) {
        return;
    }
    fw->counters.deadline_misses += missed_ticks;
    fw->tick.pending_faults |= HD_FAULT_DEADLINE_MISS;
}

static uint64_t tick_time_us(const hd_fw_t *fw)
{
    const hal_clock_t *clock = &fw->hal->clock;
    return (clock->time_us != NULL) ? clock->time_us(clock->ctx)
                                    : (uint64_t)fw->counters.ticks * HD_FW_TS_US;
}

static void check_deadline(hd_fw_t *fw, uint64_t t_us)
{
    hd_fw_tick_state_t *k = &fw->tick;
    if (k->have_prev_time && t_us - k->prev_t_us > (uint64_t)HD_FW_TS_US * 3u / 2u) {
        uint64_t missed = (t_us - k->prev_t_us + HD_FW_TS_US / 2u) / HD_FW_TS_US - 1u;
        hd_fw_note_deadline_miss(fw, missed > 0xFFFFu ? 0xFFFFu : (uint32_t)missed);
    }
    k->prev_t_us = t_us;
    k->have_prev_time = true;
}

/* ------------------------------------------------------------- requests */

/* What the background prepared takes effect here, between two samples. */
static void apply_request(hd_fw_t *fw)
{
    hd_fw_request_t *r = &fw->request;
    if (!r->pending) {
        return;
    }
    hd_fw_filter_t *k = &fw->filter;
    if (r->flags & HD_FW_REQ_PIPE) {
        fw->live_pipe ^= 1u;
        k->import_pending = fw->bg.profile.line_count > 0u; /* a new filter starts from it */
    }
    if (r->flags & HD_FW_REQ_SETTINGS) {
        fw->live_settings ^= 1u;
        if (fw->telem.countdown >= hd_fw_live(fw)->telem_divider) {
            fw->telem.countdown = 0u;
        }
    }
    if (r->flags & HD_FW_REQ_KF_RESET) {
        hd_kf_reset(&hd_fw_live_pipe(fw)->kf);
        k->import_pending = fw->bg.profile.line_count > 0u;
    }
    if (r->flags & HD_FW_REQ_BLOCK) {
        (void)hd_kf_set_block_enabled(&hd_fw_live_pipe(fw)->kf, r->block, r->enable != 0u);
    }
    if (r->flags & HD_FW_REQ_PROFILE) {
        k->import_pending = true;
    }
    if (r->flags & HD_FW_REQ_SNAPSHOT) {
        k->snapshot_pending = true;
    }
    if (r->flags & HD_FW_REQ_IDENT) {
        hd_fw_ident_begin(&fw->ident);
    }
    r->pending = 0u;
}

/* --------------------------------------------------------------- receive */

/* Commands for this node wait for the background (the queue never
 * overflows: when full, frames stay with the driver); feed-forward and
 * control frames are taken at once; the rest is counted. */
static void receive_frames(hd_fw_t *fw)
{
    hd_fw_ff_age(&fw->ff);
    const hal_can_t *can = &fw->hal->can;
    if (can->recv == NULL) {
        return;
    }
    const uint8_t node = hd_fw_live(fw)->cfg.node_id;
    for (unsigned i = 0; i < HD_FW_RX_PER_TICK; i++) {
        hal_can_frame_t f;
        /* A full queue leaves the rest with the driver: back pressure, not
         * loss (the tick is the queue's only producer: the push below then
         * always has room). */
        if (hd_fw_queue_full(&fw->cmd_queue)) {
            fw->counters.command_queue_full++;
            break;
        }
        if (can->recv(can->ctx, &f) != HAL_OK) {
            break;
        }
        uint8_t type = 0u;
        uint8_t to = 0u;
        const bool ours = (f.flags & HAL_CAN_FLAG_ERR) == 0u &&
                          hd_can_id_parse(f.id, f.flags, &type, &to) && to == node;
        if (ours && type == HD_CAN_FRAME_FEEDFORWARD) {
            fw->tick.pending_faults |= hd_fw_ff_take(&fw->ff, &hd_fw_live(fw)->cfg, &f,
                                                     &fw->counters.feedforward_frames);
            continue;
        }
        if (ours && (type == HD_CAN_FRAME_SETPOINT || type == HD_CAN_FRAME_GAINS)) {
            hd_fw_take_control_frame(fw, &f, type); /* at once, like feed-forward */
            continue;
        }
        if (!ours || type != HD_CAN_FRAME_CMD) {
            fw->counters.foreign_frames++;
            continue;
        }
        (void)hd_fw_queue_push(&fw->cmd_queue, &f); /* room: checked above */
    }
}

/* ---------------------------------------------------------------- faults */

_Static_assert(HD_FAULT_COUNT < 32u, "the fault bits fit a uint32_t below bit 31");
#define FAULT_BITS ((1u << HD_FAULT_COUNT) - 1u)

static void account_faults(hd_fw_t *fw, hd_fw_sample_t *s, uint32_t faults)
{
    hd_fw_tick_state_t *k = &fw->tick;
    const uint32_t errors = fw->counters.command_errors;
    if (errors != k->command_errors_seen) {
        k->command_errors_seen = errors;
        faults |= HD_FAULT_CMD_ERROR;
    }
    faults |= hd_fw_live(fw)->record_faults | k->pending_faults;
    k->pending_faults = 0u;
    s->faults = faults;
    fw->telem.faults |= faults;
    fw->telem.kf_status |= (uint8_t)s->kf_status;
    fw->telem.hb_faults |= faults;
    if (s->valid) {
        fw->counters.valid_samples++;
    }
    if (faults != 0u) {
        fw->counters.fault_ticks++;
        /* the set bits only: a tick with a sticky record fault would walk
         * all HD_FAULT_COUNT bits every millisecond */
        for (uint32_t left = faults & FAULT_BITS; left != 0u; left &= left - 1u) {
            fw->counters.by_fault[__builtin_ctz(left)]++;
        }
    }
    k->state = (fw->telem.hb_faults != 0u) ? HD_STATE_DEGRADED : HD_STATE_RUN;
}

/* ------------------------------------------------------------- the tick */

void hd_fw_isr(hd_fw_t *fw)
{
    if (fw->tick.ended) {
        return;
    }
    const hal_sensors_t *sen = &fw->hal->sensors;
    const uint64_t t_us = tick_time_us(fw);
    check_deadline(fw, t_us);        /* late ticks are counted and flagged */
    apply_request(fw);               /* the change the background prepared */
    receive_frames(fw);              /* commands queued; feed-forward, setpoints latched */
    const hd_fw_settings_t *set = hd_fw_live(fw);
    /* The stages fill the sample in place: nothing reads fw->last during
     * the tick, and a copy of it at the end cost ~100 instructions. */
    hd_fw_sample_t *s = &fw->last;
    uint32_t faults = 0u;
    if (!hd_fw_gauge(&fw->gauge, &set->cfg, sen, t_us, s, &faults)) { /* ADC -> N m */
        hd_fw_stop(fw);
        return;
    }
    faults |= hd_fw_encoder(&fw->encoder, set, sen, s);          /* counts -> increments */
    faults |= hd_fw_current(&fw->current, &set->cfg, sen, s);    /* motor current */
    faults |= hd_fw_ff(&fw->ff, &set->cfg, s);                   /* feed-forward, stale fallback */
    faults |= hd_fw_filter(fw, s);   /* expected torque -> Kalman filter -> filtered torque */
    /* with the faults raised between samples (a bus-off seen by a send) */
    faults |= hd_fw_control(fw, s, faults | fw->tick.pending_faults);
    account_faults(fw, s, faults);   /* fault bits, counters, state */
    fw->counters.ticks++;
    hd_fw_publish(fw, s);            /* boot report, telemetry, heartbeat, ACKs */
}
