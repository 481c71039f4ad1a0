/* hd_fw_filter: the filter stage (hd_fw_stages.h).
 *
 * Contract: once per tick after the sensors, the current channel and the
 * feed-forward latch.  Before the step it imports the stored profile when
 * one is pending and the angles are known; then hd_pipeline_sample (the
 * expected torque of filter/hd_slow.h and the Kalman step: the same call
 * hdsense analyze replays) on the live pipeline; after the step the
 * PROFILE_SAVE snapshot when asked.  Fills the sample's filtered torque,
 * ripple, T_exp and its variance, motor velocity and filter status (with
 * the filter off: filtered = raw, ripple 0; an invalid sample: NaN).
 * Returns HD_FAULT_KF_FROZEN / HD_FAULT_KF_RESET. */
#include <math.h> /* NAN: a constant, no libm call */
#include <string.h>

#include "hd_fw.h"
#include "hd_fw_internal.h"
#include "hd_trig.h"

/* Lines whose angle this joint knows: output-locked ones need the output
 * encoder (docs/design/slow-torque.md, "Absolute angles"). */
static void known_lines(const hd_fw_encoder_t *k, const hd_kf_profile_t *in,
                        hd_kf_profile_t *out)
{
    unsigned n = 0u;
    for (unsigned i = 0; i < in->line_count && i < HD_KF_MAX_BLOCKS; i++) {
        if (in->lines[i].lock == HD_KF_LOCK_MOTOR || k->output_pos_valid) {
            out->lines[n++] = in->lines[i];
        }
    }
    out->line_count = (uint8_t)n;
    out->load_nm = in->load_nm;
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
    const hd_fw_encoder_t *k = &fw->encoder;
    if (!k->pos_valid) {
        return; /* no absolute angle yet: the next good encoder reading */
    }
    fw->filter.import_pending = false;
    const hd_fw_settings_t *set = hd_fw_live(fw);
    hd_kf_profile_t p;
    known_lines(k, &fw->bg.profile, &p);
    if (p.line_count == 0u) {
        return;
    }
    hd_kf_t *kf = &hd_fw_live_pipe(fw)->kf;
    const int rc = hd_kf_profile_import(
        kf, &p, wrap_angle(hd_fw_encoder_motor_rad(k, set) - s->d_motor_angle_rad),
        wrap_angle(hd_fw_encoder_output_rad(k, set) - s->d_output_angle_rad), kf->cfg.r_nm2);
    if (rc >= 0) {
        fw->counters.profile_imports++;
    }
}

/* After this tick's step: PROFILE_SAVE's snapshot at this sample's angles. */
static void export_profile(hd_fw_t *fw)
{
    const hd_fw_encoder_t *k = &fw->encoder;
    hd_fw_filter_t *f = &fw->filter;
    const hd_fw_settings_t *set = hd_fw_live(fw);
    hd_kf_profile_t all;
    memset(&all, 0, sizeof all);
    if (k->pos_valid) {
        (void)hd_kf_profile_export(&hd_fw_live_pipe(fw)->kf, hd_fw_encoder_motor_rad(k, set),
                                   hd_fw_encoder_output_rad(k, set), &all);
    }
    known_lines(k, &all, &f->snapshot);
    f->snapshot_pending = false;
    f->snapshot_seq = f->snapshot_seq + 1u;
}

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
        fw->filter.import_pending = fw->bg.profile.line_count > 0u;
    }
    fw->counters.correction_limited += (out->status & HD_KF_STATUS_LIMITED) != 0u ? 1u : 0u;
    fw->counters.unmodelled_steps += (out->status & HD_KF_STATUS_UNMODELLED) != 0u ? 1u : 0u;
    return faults;
}

static void put_output(const hd_fw_config_t *c, const hd_kf_output_t *out, hd_fw_sample_t *s)
{
    if (!s->valid) {
        s->torque_filtered_nm = NAN;
        s->ripple_nm = out->ripple_nm;
    } else if (c->filter_enabled) {
        s->torque_filtered_nm = out->torque_filtered_nm;
        s->ripple_nm = out->ripple_nm;
    } else {
        s->torque_filtered_nm = s->torque_raw_nm;
        s->ripple_nm = 0.0f;
    }
}

uint32_t hd_fw_filter(hd_fw_t *fw, hd_fw_sample_t *s)
{
    const hd_fw_settings_t *set = hd_fw_live(fw);
    if (fw->filter.import_pending) {
        import_profile(fw, s);
    }
    const hd_pipeline_in_t in = {s->torque_raw_nm,  s->d_motor_angle_rad, s->d_output_angle_rad,
                                 s->feedforward_nm, 0.0f,                 s->motor_current_a};
    hd_pipeline_slow_t slow;
    hd_kf_output_t out;
    hd_pipeline_sample(hd_fw_live_pipe(fw), &fw->current.est, &set->current, &in, &slow, &out);
    const uint32_t faults = filter_health(fw, &out);
    if (fw->filter.snapshot_pending) {
        export_profile(fw);
    }
    s->kf_status = out.status;
    s->torque_expected_nm = slow.torque_expected_nm;
    s->torque_expected_var_nm2 = slow.torque_expected_var_nm2;
    s->motor_velocity_rad_s = slow.output_velocity_rad_s * set->cfg.gear_ratio;
    put_output(&set->cfg, &out, s);
    return faults;
}
