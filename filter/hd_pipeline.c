/* hd_pipeline: see hd_pipeline.h. */
#include "hd_pipeline.h"

#include <math.h> /* NAN: a constant, no libm call */

hd_kf_err_t hd_pipeline_init(hd_pipeline_t *p, const hd_kf_config_t *kf_cfg,
                             const hd_expected_config_t *expected_cfg,
                             float track_bandwidth_hz)
{
    hd_kf_err_t err = hd_kf_init(&p->kf, kf_cfg);
    if (err != HD_KF_OK) {
        return err;
    }
    err = hd_track_init(&p->output_track, kf_cfg->ts_s, track_bandwidth_hz);
    if (err != HD_KF_OK) {
        return err;
    }
    err = hd_expected_config_check(expected_cfg);
    if (err != HD_KF_OK) {
        return err;
    }
    p->expected = *expected_cfg;
    p->torque_expected_nm = 0.0f;
    return HD_KF_OK;
}

/* Inlined into both entry points: the tick's path pays one call, not two. */
static inline void step(hd_pipeline_t *p, float torque_meas_nm, float d_motor_angle_rad,
                        float d_output_angle_rad, float feedforward_nm, float feedforward_var_nm2,
                        hd_kf_output_t *out)
{
    (void)hd_track_update(&p->output_track, d_output_angle_rad);
    p->torque_expected_nm = hd_expected_torque_nm(
        &p->expected, p->output_track.vel_rad_s, p->output_track.acc_rad_s2,
        feedforward_nm);
    const hd_kf_input_t in = {
        .torque_meas_nm = torque_meas_nm,
        .torque_expected_nm = p->torque_expected_nm,
        .d_motor_angle_rad = d_motor_angle_rad,
        .d_output_angle_rad = d_output_angle_rad,
        .torque_expected_var_nm2 = feedforward_var_nm2,
    };
    hd_kf_step(&p->kf, &in, out);
}

void hd_pipeline_step(hd_pipeline_t *p, float torque_meas_nm,
                      float d_motor_angle_rad, float d_output_angle_rad,
                      float feedforward_nm, float feedforward_var_nm2, hd_kf_output_t *out)
{
    step(p, torque_meas_nm, d_motor_angle_rad, d_output_angle_rad, feedforward_nm,
         feedforward_var_nm2, out);
}

void hd_pipeline_sample(hd_pipeline_t *p, hd_slow_current_t *cur,
                        const hd_slow_current_config_t *cc, const hd_pipeline_in_t *in,
                        hd_pipeline_slow_t *slow, hd_kf_output_t *out)
{
    const float w = hd_slow_output_velocity_rad_s(cc, in->d_motor_angle_rad);
    float cur_var_nm2;
    const float cur_nm =
        hd_slow_current_nm(cur, cc, &p->expected, in->motor_current_a, w, &cur_var_nm2);
    const float var_nm2 = cur_var_nm2 + in->feedforward_var_nm2;
    step(p, in->torque_meas_nm, in->d_motor_angle_rad, in->d_output_angle_rad,
         in->feedforward_nm + cur_nm, var_nm2, out);
    if (slow != NULL) {
        slow->torque_expected_nm = p->torque_expected_nm;
        slow->torque_expected_var_nm2 = var_nm2;
        slow->current_nm = cur_nm;
        slow->output_velocity_rad_s = w;
    }
}

static float at(const float *a, size_t i, float none)
{
    return a != NULL ? a[i] : none;
}

static void store(float *dst, size_t i, float v)
{
    if (dst != NULL) {
        dst[i] = v;
    }
}

void hd_pipeline_run(hd_pipeline_t *p, const hd_pipeline_io_t *io)
{
    hd_kf_output_t out;
    hd_pipeline_slow_t slow;
    float amp_prior[HD_KF_MAX_BLOCKS];
    /* no current term: a zero configuration (nm_per_a = 0), a spare state */
    static const hd_slow_current_config_t no_current = {{0.0f, 0.0f, 0.0f, 0.0f, 0.0f, 0.0f},
                                                        1.0f, 0.0f, 1.0f, 1.0f};
    hd_slow_current_t spare = {0.0f, 0.0f, 0.0f, 0.0f, 0.0f, 0u};
    const int with_current = io->current != NULL && io->current_state != NULL;
    const hd_slow_current_config_t *cc = with_current ? io->current : &no_current;
    hd_slow_current_t *cur = with_current ? io->current_state : &spare;
    for (size_t i = 0; i < io->n; i++) {
        const hd_pipeline_in_t in = {io->torque_meas_nm[i], io->d_motor_angle_rad[i],
                                     io->d_output_angle_rad[i], at(io->feedforward_nm, i, 0.0f),
                                     at(io->feedforward_var_nm2, i, 0.0f),
                                     at(io->motor_current_a, i, (float)NAN)};
        if (io->amplitude_nm != NULL) {
            for (unsigned b = 0; b < HD_KF_MAX_BLOCKS; b++) {
                amp_prior[b] = hd_kf_block_amplitude_nm(&p->kf, b);
            }
        }
        hd_pipeline_sample(p, cur, cc, &in, &slow, &out);
        store(io->torque_filtered_nm, i, out.torque_filtered_nm);
        store(io->ripple_nm, i, out.ripple_nm);
        store(io->offset_nm, i, out.offset_nm);
        store(io->innovation_nm, i, out.innovation_nm);
        store(io->innovation_var_nm2, i, out.innovation_var_nm2);
        store(io->torque_expected_nm, i, p->torque_expected_nm);
        store(io->output_velocity_rad_s, i, p->output_track.vel_rad_s);
        store(io->torque_expected_var_nm2, i, slow.torque_expected_var_nm2);
        if (io->amplitude_nm != NULL) {
            for (unsigned b = 0; b < HD_KF_MAX_BLOCKS; b++) {
                io->amplitude_nm[i * HD_KF_MAX_BLOCKS + b] =
                    hd_kf_block_row(&p->kf, b) * amp_prior[b];
            }
        }
        if (io->status != NULL) {
            io->status[i] = out.status;
        }
    }
}
