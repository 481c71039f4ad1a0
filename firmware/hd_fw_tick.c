/* hd_fw_tick: the 1 kHz tick, hd_fw_isr.  Read hd_fw_isr at the bottom
 * first: each step is one function above it, or in hd_fw_sense.c (the
 * sensors and the slow-torque inputs) and hd_fw_publish.c (what the tick
 * sends). */
#include <math.h> /* isfinite, NAN: compiler builtins, no libm call */
#include <string.h>

#include "hd_fw.h"
#include "hd_fw_internal.h"
#include "hd_trig.h"

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
    hd_fw_tick_state_t *k = &fw->tick;
    if (r->flags & HD_FW_REQ_PIPE) {
        fw->live_pipe ^= 1u;
        k->import_pending = fw->bg.profile.line_count > 0u; /* a new filter starts from it */
    }
    if (r->flags & HD_FW_REQ_SETTINGS) {
        fw->live_settings ^= 1u;
        if (fw->tick.telem_countdown >= hd_fw_live(fw)->telem_divider) {
            fw->tick.telem_countdown = 0u;
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
    r->pending = 0u;
}

/* --------------------------------------------------------------- receive */

/* A feed-forward frame is latched with this tick, or flagged and ignored
 * (malformed, not finite, beyond the torque limit: never fed to the
 * filter).  A repeated sequence number is not new data.  With
 * feedforward_timeout_ms = 0 no feed-forward is expected: frames are
 * ignored. */
static void take_feedforward(hd_fw_t *fw, const hal_can_frame_t *f)
{
    const hd_fw_config_t *c = &hd_fw_live(fw)->cfg;
    hd_fw_tick_state_t *k = &fw->tick;
    if (c->feedforward_timeout_ms == 0u) {
        return;
    }
    hd_can_feedforward_t ff;
    if (hd_can_decode_feedforward(f, &ff) != HD_CAN_RES_OK || ff.torque_nm > c->torque_limit_nm ||
        ff.torque_nm < -c->torque_limit_nm) {
        k->pending_faults |= HD_FAULT_FF_REJECTED;
        return;
    }
    if (k->ff_have && ff.seq == k->ff_seq) {
        return;
    }
    k->ff_have = true;
    k->ff_seq = ff.seq;
    k->ff_nm = ff.torque_nm;
    k->ff_age_ticks = 0u;
    fw->counters.feedforward_frames++;
}

/* Commands for this node wait for the background (the queue never
 * overflows: when full, frames stay with the driver); feed-forward and
 * control frames are taken at once; the rest is counted. */
static void receive_frames(hd_fw_t *fw)
{
    if (fw->tick.ff_age_ticks < UINT32_MAX) {
        fw->tick.ff_age_ticks++; /* the latched feed-forward is one tick older */
    }
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
            take_feedforward(fw, &f);
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

/* ------------------------------------------------------------- profiles */

static float angle_of(uint32_t pos, float rad_per_count)
{
    const float a = (float)pos * rad_per_count;
    return a < HD_TWO_PI_F ? a : 0.0f; /* (cpr - 1) / cpr can round up to 2 pi */
}

/* Lines whose angle this joint knows: output-locked ones need the output
 * encoder (docs/design/slow-torque.md, "Absolute angles"). */
static void known_lines(const hd_fw_tick_state_t *k, const hd_kf_profile_t *in,
                        hd_kf_profile_t *out)
{
    unsigned n = 0u;
    for (unsigned i = 0; i < in->line_count && i < HD_KF_MAX_BLOCKS; i++) {
        if (in->lines[i].lock == HD_KF_LOCK_MOTOR || k->output_pos_valid) {
            out->lines[n++] = in->lines[i];
        }
    }
    out->line_count = (uint8_t)n;
}

static float wrap_angle(float a)
{
    if (a < 0.0f) {
        a += HD_TWO_PI_F;
    }
    return (a >= 0.0f && a < HD_TWO_PI_F) ? a : 0.0f;
}

/* Before this tick's step: the live filter takes bg.profile at the angles
 * of the sample before this one (this sample's less its increments, which
 * the step turns it by), so that its prediction for this sample is the
 * profile at this sample's angles (hd_kf.h, "Which angle"; a first reading
 * has no increment). */
static void import_profile(hd_fw_t *fw, const hd_fw_sample_t *s)
{
    hd_fw_tick_state_t *k = &fw->tick;
    if (!k->pos_valid) {
        return; /* no absolute angle yet: the next good encoder reading */
    }
    k->import_pending = false;
    const hd_fw_settings_t *set = hd_fw_live(fw);
    hd_kf_profile_t p;
    known_lines(k, &fw->bg.profile, &p);
    if (p.line_count == 0u) {
        return;
    }
    hd_kf_t *kf = &hd_fw_live_pipe(fw)->kf;
    const int rc = hd_kf_profile_import(
        kf, &p,
        wrap_angle(angle_of(k->motor_pos, set->motor_rad_per_count) - s->d_motor_angle_rad),
        wrap_angle(angle_of(k->output_pos, set->output_rad_per_count) - s->d_output_angle_rad),
        kf->cfg.r_nm2);
    if (rc >= 0) {
        fw->counters.profile_imports++;
    }
}

/* After this tick's step: PROFILE_SAVE's snapshot at this sample's angles. */
static void export_profile(hd_fw_t *fw)
{
    hd_fw_tick_state_t *k = &fw->tick;
    const hd_fw_settings_t *set = hd_fw_live(fw);
    hd_kf_profile_t all;
    memset(&all, 0, sizeof all);
    if (k->pos_valid) {
        (void)hd_kf_profile_export(&hd_fw_live_pipe(fw)->kf,
                                   angle_of(k->motor_pos, set->motor_rad_per_count),
                                   angle_of(k->output_pos, set->output_rad_per_count), &all);
    }
    known_lines(k, &all, &k->snapshot);
    k->snapshot_pending = false;
    k->snapshot_seq = k->snapshot_seq + 1u;
}

/* ------------------------------------------------------------- pipeline */

/* What the step says of the filter: frozen blocks, a restart (the next
 * tick imports the stored profile again); the correction at its limit and
 * an innovation beyond the held jump gate (an effect the model lacks) are
 * counted, and travel as the step's status bits in TELEM_B. */
static uint32_t filter_health(hd_fw_t *fw, const hd_kf_output_t *out)
{
    uint32_t faults = 0u;
    if ((out->status & HD_KF_STATUS_FROZEN) != 0u) {
        faults |= HD_FAULT_KF_FROZEN;
    }
    if ((out->status & HD_KF_STATUS_RESET) != 0u) {
        faults |= HD_FAULT_KF_RESET;
        fw->tick.import_pending = fw->bg.profile.line_count > 0u;
    }
    fw->counters.correction_limited += (out->status & HD_KF_STATUS_LIMITED) != 0u ? 1u : 0u;
    fw->counters.unmodelled_steps += (out->status & HD_KF_STATUS_UNMODELLED) != 0u ? 1u : 0u;
    return faults;
}

static uint32_t run_pipeline(hd_fw_t *fw, hd_fw_sample_t *s)
{
    const hd_fw_config_t *c = &hd_fw_live(fw)->cfg;
    hd_pipeline_t *p = hd_fw_live_pipe(fw);
    hd_fw_tick_state_t *k = &fw->tick;
    uint32_t faults = 0u;
    if (k->import_pending) {
        import_profile(fw, s);
    }
    s->feedforward_nm = hd_fw_feedforward_nm(fw, &faults);
    float slow_var_nm2;
    const float slow_nm = s->feedforward_nm + hd_fw_current_torque_nm(fw, p, s, &slow_var_nm2);
    hd_kf_output_t out;
    hd_pipeline_step(p, s->torque_raw_nm, s->d_motor_angle_rad, s->d_output_angle_rad, slow_nm,
                     slow_var_nm2, &out);
    faults |= filter_health(fw, &out);
    if (k->snapshot_pending) {
        export_profile(fw);
    }
    s->kf_status = out.status;
    s->torque_expected_nm = p->torque_expected_nm;
    s->torque_expected_var_nm2 = slow_var_nm2;
    s->motor_velocity_rad_s = p->output_track.vel_rad_s * c->gear_ratio;
    if (!s->valid) {
        s->torque_filtered_nm = NAN;
        s->ripple_nm = out.ripple_nm;
    } else if (c->filter_enabled) {
        s->torque_filtered_nm = out.torque_filtered_nm;
        s->ripple_nm = out.ripple_nm;
    } else {
        s->torque_filtered_nm = s->torque_raw_nm;
        s->ripple_nm = 0.0f;
    }
    return faults;
}

/* ---------------------------------------------------------------- faults */

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
    k->telem_faults |= faults;
    k->telem_kf_status |= (uint8_t)s->kf_status;
    k->hb_faults |= faults;
    if (s->valid) {
        fw->counters.valid_samples++;
    }
    if (faults != 0u) {
        fw->counters.fault_ticks++;
        for (unsigned bit = 0; bit < HD_FAULT_COUNT; bit++) {
            if ((faults & (1u << bit)) != 0u) {
                fw->counters.by_fault[bit]++;
            }
        }
    }
    k->state = (k->hb_faults != 0u) ? HD_STATE_DEGRADED : HD_STATE_RUN;
}

/* ------------------------------------------------------------- the tick */

void hd_fw_isr(hd_fw_t *fw)
{
    if (fw->tick.ended) {
        return;
    }
    uint64_t t_us = tick_time_us(fw);
    check_deadline(fw, t_us);
    apply_request(fw);
    receive_frames(fw);
    hd_fw_sample_t s;
    bool ended = false;
    uint32_t faults = hd_fw_sense(fw, t_us, &s, &ended);
    if (ended) {
        hd_fw_stop(fw);
        return;
    }
    faults |= run_pipeline(fw, &s);
    /* with the faults raised between samples (a bus-off seen by a send) */
    faults |= hd_fw_control(fw, &s, faults | fw->tick.pending_faults);
    account_faults(fw, &s, faults);
    fw->last = s;
    fw->counters.ticks++;
    hd_fw_publish(fw, &s);
}
