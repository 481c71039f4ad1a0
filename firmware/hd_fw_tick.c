/* hd_fw_tick: the 1 kHz tick, hd_fw_isr.  Read hd_fw_isr at the bottom
 * first: each step is one function above it. */
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
        k->kf_fresh = true; /* a new filter starts from the profile */
        k->import_pending = fw->bg.profile.line_count > 0u;
    }
    if (r->flags & HD_FW_REQ_SETTINGS) {
        fw->live_settings ^= 1u;
        if (fw->tick.telem_countdown >= hd_fw_live(fw)->telem_divider) {
            fw->tick.telem_countdown = 0u;
        }
    }
    if (r->flags & HD_FW_REQ_KF_RESET) {
        hd_kf_reset(&hd_fw_live_pipe(fw)->kf);
        k->kf_fresh = true;
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
 * overflows: when full, frames stay with the driver); feed-forward frames
 * are taken at once; the rest is counted. */
static void receive_frames(hd_fw_t *fw)
{
    const hal_can_t *can = &fw->hal->can;
    if (can->recv == NULL) {
        return;
    }
    const uint8_t node = hd_fw_live(fw)->cfg.node_id;
    for (unsigned i = 0; i < HD_FW_RX_PER_TICK; i++) {
        hal_can_frame_t f;
        /* A full queue leaves the rest with the driver: back pressure, not loss. */
        if (hd_fw_queue_full(&fw->cmd_queue) || can->recv(can->ctx, &f) != HAL_OK) {
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
        if (!ours || type != HD_CAN_FRAME_CMD) {
            fw->counters.foreign_frames++;
            continue;
        }
        if (!hd_fw_queue_push(&fw->cmd_queue, &f)) {
            fw->counters.commands_dropped++;
            fw->tick.pending_faults |= HD_FAULT_CMD_ERROR;
        }
    }
}

/* ----------------------------------------------------------------- sense */

static int32_t abs32(int32_t v)
{
    return v < 0 ? (v == INT32_MIN ? INT32_MAX : -v) : v;
}

/* One encoder channel: the wrapped count delta, with glitch rejection. */
static int32_t encoder_delta(uint32_t counts, uint32_t *prev, int32_t *last_good, int32_t max_delta,
                             bool *glitch)
{
    int32_t d = (int32_t)(counts - *prev); /* modulo 2^32: wraps are fine */
    *prev = counts; /* track the raw count so a one-sample spike costs no angle */
    if (abs32(d) > max_delta) {
        *glitch = true;
        return *last_good;
    }
    *last_good = d;
    return d;
}

/* (pos + d) modulo cpr; |d| is below the glitch limit (<= 1e9) and
 * pos < cpr <= 2^24, so the sum fits an int32. */
static uint32_t wrap_pos(uint32_t pos, int32_t d, uint32_t cpr)
{
    int32_t r = ((int32_t)pos + d) % (int32_t)cpr;
    return (uint32_t)(r < 0 ? r + (int32_t)cpr : r);
}

/* The absolute angles the profiles refer to: the first good reading modulo
 * cpr, then every increment the filter is given (glitch replacements
 * included, so they follow the filter's own phase). */
static void track_positions(hd_fw_tick_state_t *k, const hd_fw_settings_t *set, bool good,
                            const hal_encoder_sample_t *enc, int32_t dm, int32_t dout)
{
    const uint32_t mcpr = set->cfg.motor_cpr;
    const uint32_t ocpr = set->cfg.output_cpr;
    if (k->pos_valid && (mcpr != k->pos_motor_cpr || ocpr != k->pos_output_cpr)) {
        k->pos_valid = false; /* counted in other units: start again from a reading */
    }
    if (!k->pos_valid) {
        if (!good) {
            return;
        }
        k->pos_valid = true;
        k->pos_motor_cpr = mcpr;
        k->pos_output_cpr = ocpr;
        k->motor_pos = enc->motor_counts % mcpr;
        k->output_pos_valid = enc->has_output;
        k->output_pos = enc->has_output ? enc->output_counts % ocpr : 0u;
        return;
    }
    k->motor_pos = wrap_pos(k->motor_pos, dm, mcpr);
    if (!enc->has_output) {
        k->output_pos_valid = false;
    } else if (k->output_pos_valid) {
        k->output_pos = wrap_pos(k->output_pos, dout, ocpr);
    } else if (good) {
        /* the output encoder (back): its counts are absolute */
        k->output_pos_valid = true;
        k->output_pos = enc->output_counts % ocpr;
    }
}

static uint32_t read_encoders(hd_fw_t *fw, hd_fw_sample_t *s)
{
    const hd_fw_settings_t *set = hd_fw_live(fw);
    const hal_sensors_t *sen = &fw->hal->sensors;
    hd_fw_tick_state_t *k = &fw->tick;
    hal_encoder_sample_t enc;
    memset(&enc, 0, sizeof enc);
    int rc = (sen->encoder_read != NULL) ? sen->encoder_read(sen->ctx, &enc) : HAL_ERR_NO_DATA;
    uint32_t faults = 0u;
    int32_t dm = 0;
    int32_t dout = 0;
    k->first_reading = false;
    if (rc != HAL_OK || enc.fault) {
        /* No usable counts: assume the previous motion continues. */
        faults |= HD_FAULT_ENC_FAULT;
        dm = k->last_good_motor_delta;
        dout = k->last_good_output_delta;
        k->prev_motor_counts += (uint32_t)dm;
        k->prev_output_counts += (uint32_t)dout;
        enc.has_output = k->output_present;
        enc.motor_counts = k->prev_motor_counts;
        enc.output_counts = k->prev_output_counts;
    } else if (!k->have_prev) {
        k->have_prev = true;
        k->first_reading = true;
        k->prev_motor_counts = enc.motor_counts;
        k->prev_output_counts = enc.output_counts;
        k->output_present = enc.has_output;
    } else {
        bool glitch = false;
        k->output_present = enc.has_output;
        dm = encoder_delta(enc.motor_counts, &k->prev_motor_counts, &k->last_good_motor_delta,
                           set->max_motor_delta_counts, &glitch);
        if (enc.has_output) {
            dout = encoder_delta(enc.output_counts, &k->prev_output_counts,
                                 &k->last_good_output_delta, set->max_output_delta_counts, &glitch);
        }
        if (glitch) {
            faults |= HD_FAULT_ENC_GLITCH;
        }
    }
    track_positions(k, set, rc == HAL_OK && !enc.fault, &enc, dm, dout);
    s->motor_counts = enc.motor_counts;
    s->output_counts = enc.output_counts;
    s->has_output = enc.has_output;
    s->d_motor_angle_rad = (float)dm * set->motor_rad_per_count;
    s->d_output_angle_rad = enc.has_output ? (float)dout * set->output_rad_per_count
                                           : s->d_motor_angle_rad / set->cfg.gear_ratio;
    return faults;
}

static uint32_t read_torque(const hd_fw_t *fw, int adc_rc, const hal_adc_sample_t *adc,
                            hd_fw_sample_t *s)
{
    const hd_fw_config_t *c = &hd_fw_live(fw)->cfg;
    s->bridge_counts = adc->bridge_counts;
    s->bridge_v = NAN;
    s->torque_raw_nm = NAN;
    if (adc_rc == HAL_ERR_FAULT) {
        return HD_FAULT_OPEN_BRIDGE;
    }
    if (adc_rc != HAL_OK) {
        return HD_FAULT_ADC_ERROR;
    }
    if (adc->saturated) {
        return HD_FAULT_ADC_SATURATED;
    }
    float v = (float)adc->bridge_counts * c->adc_volts_per_count;
    float t = c->calib_gain_nm_per_v * (v - c->calib_offset_v);
    s->bridge_v = v;
    if (!isfinite(t)) {
        return HD_FAULT_ADC_ERROR;
    }
    if (t > c->torque_limit_nm || t < -c->torque_limit_nm) {
        return HD_FAULT_TORQUE_RANGE;
    }
    s->torque_raw_nm = t;
    return 0u;
}

static void remember_for_tare(hd_fw_tick_state_t *k, float bridge_v)
{
    k->tare_v[k->tare_next] = bridge_v;
    k->tare_next = (k->tare_next + 1u) % HD_FW_TARE_TICKS;
    if (k->tare_n < HD_FW_TARE_TICKS) {
        k->tare_n = k->tare_n + 1u;
    }
}

/* The optional motor-current channel.  A failed or non-finite reading
 * holds the last good value; it is a fault only when T_exp uses it. */
static uint32_t read_current(hd_fw_t *fw, hd_fw_sample_t *s)
{
    const hal_sensors_t *sen = &fw->hal->sensors;
    hd_fw_tick_state_t *k = &fw->tick;
    s->motor_current_a = NAN;
    if (sen->current_read == NULL) {
        return 0u;
    }
    hal_current_sample_t cur;
    memset(&cur, 0, sizeof cur);
    const int rc = sen->current_read(sen->ctx, &cur);
    const bool good = rc == HAL_OK && !cur.fault && isfinite(cur.motor_current_a);
    if (good) {
        k->current_a = cur.motor_current_a;
    }
    s->motor_current_a = k->current_a;
    return (!good && hd_fw_live(fw)->cfg.current.nm_per_a > 0.0f) ? HD_FAULT_CURRENT_ERROR : 0u;
}

/* ADC and encoders into *s; returns the sensor faults.  *ended: the sample
 * source is exhausted (replay, simulation end). */
static uint32_t sense(hd_fw_t *fw, uint64_t t_us, hd_fw_sample_t *s, bool *ended)
{
    const hal_t *hal = fw->hal;
    hal_adc_sample_t adc;
    memset(&adc, 0, sizeof adc);
    memset(s, 0, sizeof *s);
    s->t_us = t_us;
    int adc_rc = hal->sensors.adc_read(hal->sensors.ctx, &adc);
    *ended = adc_rc == HAL_ERR_END;
    if (*ended) {
        return 0u;
    }
    uint32_t faults = read_torque(fw, adc_rc, &adc, s);
    s->valid = faults == 0u;
    if (s->valid) {
        remember_for_tare(&fw->tick, s->bridge_v);
    }
    faults |= read_encoders(fw, s);
    return faults | read_current(fw, s);
}

/* ------------------------------------------------------------- profiles */

static float angle_of(uint32_t pos, float rad_per_count)
{
    const float a = (float)pos * rad_per_count;
    return a < HD_TWO_PI_F ? a : 0.0f; /* (cpr - 1) / cpr can round up to 2 pi */
}

/* Lines whose angle this joint knows: output-locked ones need the output
 * encoder (docs/slow-torque.md, "Absolute angles"). */
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

/* Before this tick's step: the live filter takes bg.profile so that its
 * prediction for this sample is the profile at this sample's angles, and
 * after the step it leads by this tick's increment, as a filter that has
 * learned at this speed does (hd_kf.h, "Which angle": the filter adds its
 * last increment, 0 when fresh, to the angle passed).  The very first
 * sample has no increment (no previous reading): the import is repeated
 * at the second, so the lead is the joint's real one. */
static void import_profile(hd_fw_t *fw)
{
    hd_fw_tick_state_t *k = &fw->tick;
    if (!k->pos_valid) {
        return; /* no absolute angle yet: the next good encoder reading */
    }
    k->import_pending = k->first_reading;
    const hd_fw_settings_t *set = hd_fw_live(fw);
    hd_kf_profile_t p;
    known_lines(k, &fw->bg.profile, &p);
    if (p.line_count == 0u) {
        return;
    }
    const float lead_m = k->kf_fresh ? 0.0f : fw->last.step_motor_rad;
    const float lead_o = k->kf_fresh ? 0.0f : fw->last.step_output_rad;
    hd_kf_t *kf = &hd_fw_live_pipe(fw)->kf;
    const int rc = hd_kf_profile_import(
        kf, &p, wrap_angle(angle_of(k->motor_pos, set->motor_rad_per_count) - lead_m),
        wrap_angle(angle_of(k->output_pos, set->output_rad_per_count) - lead_o), kf->cfg.r_nm2);
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

/* ----------------------------------------------------------- slow torque */

/* The feed-forward in T_exp: the latched value while fresh; once older than
 * the timeout, FF_STALE and a ramp to zero over feedforward_ramp_ms from the
 * last value (docs/slow-torque.md, "Feed-forward"). */
static float feedforward_now(hd_fw_t *fw, uint32_t *faults)
{
    const hd_fw_config_t *c = &hd_fw_live(fw)->cfg;
    hd_fw_tick_state_t *k = &fw->tick;
    if (c->feedforward_timeout_ms == 0u) {
        return 0.0f;
    }
    if (k->ff_have && k->ff_age_ticks <= c->feedforward_timeout_ms) {
        k->ff_stale_ticks = 0u;
        k->ff_stale_from_nm = k->ff_nm;
        return k->ff_nm;
    }
    *faults |= HD_FAULT_FF_STALE;
    if (k->ff_stale_ticks < UINT32_MAX) {
        k->ff_stale_ticks++;
    }
    const uint32_t ramp = c->feedforward_ramp_ms;
    if (k->ff_stale_ticks >= ramp) {
        return 0.0f;
    }
    return k->ff_stale_from_nm * (1.0f - (float)k->ff_stale_ticks / (float)ramp);
}

/* T_cur of hd_expected.h on inputs low-passed alike: the current, the
 * output velocity (from the motor increments: 1/gear ratio finer than the
 * output encoder) and the derivative of the filtered velocity, through the
 * same two first-order stages.  T_exp is the slow torque: unfiltered, the
 * drive's current noise (N kt times tens of mA) and the rotor's inertia
 * torque against a lagging acceleration estimate would enter the filter's
 * innovation (docs/slow-torque.md, "Motor current"). */
static float current_torque_nm(hd_fw_t *fw, const hd_pipeline_t *p, const hd_fw_sample_t *s)
{
    const hd_fw_settings_t *set = hd_fw_live(fw);
    const hd_fw_config_t *c = &set->cfg;
    hd_fw_tick_state_t *k = &fw->tick;
    if (!(c->current.nm_per_a > 0.0f) || !isfinite(s->motor_current_a)) {
        k->cur_primed = false;
        return 0.0f;
    }
    const float a = set->current_alpha;
    const float w = s->d_motor_angle_rad / (c->gear_ratio * HD_FW_TS_S);
    if (!k->cur_primed) {
        k->cur_i1 = k->cur_i2 = s->motor_current_a;
        k->cur_w1 = k->cur_w2 = w;
        k->cur_acc = 0.0f;
        k->cur_primed = true;
    } else {
        k->cur_i1 += a * (s->motor_current_a - k->cur_i1);
        k->cur_i2 += a * (k->cur_i1 - k->cur_i2);
        k->cur_w1 += a * (w - k->cur_w1);
        const float dw = a * (k->cur_w1 - k->cur_w2);
        k->cur_w2 += dw;
        k->cur_acc = dw / HD_FW_TS_S;
    }
    return hd_expected_current_nm(&c->current, &p->expected, k->cur_i2, k->cur_w2, k->cur_acc);
}

/* ------------------------------------------------------------- pipeline */

/* The filter turns its prediction for the next sample by the increment it
 * is given with this one (hd_kf.h); the increment to the next sample is
 * not known yet, so it is predicted from the last two (constant
 * acceleration): 2 d_k - d_k-1.  With d_k itself the prediction keeps the
 * speed of the moment it learned and every speed change leaves motor-locked
 * blocks a phase error of order x the change (docs/slow-torque.md,
 * "Increment prediction").  The first reading's zero increment is not
 * real: no prediction from it. */
static void step_increments(hd_fw_t *fw, hd_fw_sample_t *s)
{
    hd_fw_tick_state_t *k = &fw->tick;
    const bool predict = hd_fw_live(fw)->cfg.predict_increment != 0u && k->prev_inc_valid;
    s->step_motor_rad = predict ? 2.0f * s->d_motor_angle_rad - k->prev_dm_rad
                                : s->d_motor_angle_rad;
    s->step_output_rad = predict ? 2.0f * s->d_output_angle_rad - k->prev_dout_rad
                                 : s->d_output_angle_rad;
    k->prev_dm_rad = s->d_motor_angle_rad;
    k->prev_dout_rad = s->d_output_angle_rad;
    k->prev_inc_valid = !k->first_reading;
}

static uint32_t run_pipeline(hd_fw_t *fw, hd_fw_sample_t *s)
{
    const hd_fw_config_t *c = &hd_fw_live(fw)->cfg;
    hd_pipeline_t *p = hd_fw_live_pipe(fw);
    hd_fw_tick_state_t *k = &fw->tick;
    uint32_t faults = 0u;
    if (k->import_pending) {
        import_profile(fw);
    }
    s->feedforward_nm = feedforward_now(fw, &faults);
    const float slow_nm = s->feedforward_nm + current_torque_nm(fw, p, s);
    hd_kf_output_t out;
    step_increments(fw, s);
    hd_pipeline_step(p, s->torque_raw_nm, s->step_motor_rad, s->step_output_rad, slow_nm,
                     &out);
    k->kf_fresh = false;
    if (k->snapshot_pending) {
        export_profile(fw);
    }
    s->kf_status = out.status;
    s->torque_expected_nm = p->torque_expected_nm;
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
    if ((out.status & HD_KF_STATUS_FROZEN) != 0u) {
        faults |= HD_FAULT_KF_FROZEN;
    }
    if ((out.status & HD_KF_STATUS_RESET) != 0u) {
        faults |= HD_FAULT_KF_RESET;
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

/* --------------------------------------------------------------- publish */

static void send_frame(hd_fw_t *fw, const hal_can_frame_t *f)
{
    const hal_can_t *can = &fw->hal->can;
    if (can->send == NULL) {
        return;
    }
    int rc = can->send(can->ctx, f);
    if (rc == HAL_OK) {
        return;
    }
    /* Dropped: the fault shows in the next frame that gets through. */
    fw->counters.frames_dropped++;
    fw->tick.pending_faults |= (rc == HAL_ERR_FAULT) ? HD_FAULT_CAN_BUS_OFF : HD_FAULT_CAN_TX_FULL;
}

static void send_boot(hd_fw_t *fw)
{
    const hd_fw_settings_t *set = hd_fw_live(fw);
    const hal_boot_info_t *b = &fw->bg.boot;
    hd_can_boot_t boot = {(uint8_t)b->reset_cause, b->fault_valid, fw->bg.config_from_record,
                          b->fault_valid ? b->fault_pc : 0u, (uint8_t)HD_CAN_PROTOCOL_VERSION,
                          set->config_status};
    hal_can_frame_t f;
    hd_can_encode_boot(set->cfg.node_id, &boot, &f);
    send_frame(fw, &f);
    fw->tick.boot_sent = true;
}

static void send_telemetry(hd_fw_t *fw, const hd_fw_sample_t *s)
{
    const hd_fw_settings_t *set = hd_fw_live(fw);
    hd_fw_tick_state_t *k = &fw->tick;
    if (set->telem_divider == 0u) {
        return;
    }
    if (k->telem_countdown > 0u) {
        k->telem_countdown--;
        return;
    }
    k->telem_countdown = set->telem_divider - 1u;
    hd_can_telem_t t = {s->torque_filtered_nm, s->torque_raw_nm, s->ripple_nm, s->valid,
                        s->motor_velocity_rad_s, k->telem_faults, k->telem_kf_status,
                        k->telem_seq};
    k->telem_faults = 0u;
    k->telem_kf_status = 0u;
    hal_can_frame_t a;
    hal_can_frame_t b;
    hd_can_encode_telem(set->cfg.node_id, &t, &a, &b);
    send_frame(fw, &a);
    send_frame(fw, &b);
    const uint16_t every = set->cfg.angle_telemetry_every;
    if (every != 0u && k->telem_pairs % every == 0u) {
        hd_can_angle_t c = {s->motor_counts, s->output_counts, s->has_output, k->telem_seq};
        hd_can_encode_angle(set->cfg.node_id, &c, &a);
        send_frame(fw, &a);
    }
    k->telem_pairs++;
    k->telem_seq++;
    fw->counters.telemetry_frames++;
}

static uint16_t sat16(uint32_t v)
{
    return v > 0xFFFFu ? 0xFFFFu : (uint16_t)v;
}

static void send_heartbeat(hd_fw_t *fw, bool now)
{
    hd_fw_tick_state_t *k = &fw->tick;
    if (k->hb_countdown > 0u && !now) {
        k->hb_countdown--;
        return;
    }
    k->hb_countdown = HD_FW_HEARTBEAT_TICKS - 1u;
    const hd_fw_settings_t *set = hd_fw_live(fw);
    hd_can_heartbeat_t h = {k->state, k->hb_faults, sat16(fw->counters.deadline_misses),
                            set->calib_status, set->config_status, set->profile_status};
    k->hb_faults = 0u;
    hal_can_frame_t f;
    hd_can_encode_heartbeat(set->cfg.node_id, &h, &f);
    send_frame(fw, &f);
}

/* ACKs were encoded by the background; the tick owns the transmitter. */
static void send_acks(hd_fw_t *fw)
{
    hal_can_frame_t f;
    for (unsigned i = 0; i < HD_FW_ACKS_PER_TICK && hd_fw_queue_pop(&fw->ack_queue, &f); i++) {
        send_frame(fw, &f);
    }
}

static void publish(hd_fw_t *fw, const hd_fw_sample_t *s)
{
    if (!fw->tick.boot_sent) {
        send_boot(fw);
    }
    send_telemetry(fw, s);
    send_heartbeat(fw, false);
    send_acks(fw);
}

static void stop(hd_fw_t *fw)
{
    fw->tick.ended = true;
    fw->tick.state = HD_STATE_STOPPED;
    send_heartbeat(fw, true); /* say so at once */
    send_acks(fw);
}

/* ------------------------------------------------------------- the tick */

void hd_fw_isr(hd_fw_t *fw)
{
    if (fw->tick.ended) {
        return;
    }
    uint64_t t_us = tick_time_us(fw);
    check_deadline(fw, t_us);
    if (fw->tick.ff_age_ticks < UINT32_MAX) {
        fw->tick.ff_age_ticks++;
    }
    apply_request(fw);
    receive_frames(fw);
    hd_fw_sample_t s;
    bool ended = false;
    uint32_t faults = sense(fw, t_us, &s, &ended);
    if (ended) {
        stop(fw);
        return;
    }
    faults |= run_pipeline(fw, &s);
    account_faults(fw, &s, faults);
    fw->last = s;
    fw->counters.ticks++;
    publish(fw, &s);
}
