/*
 * hd_pipeline: one sample of the torque path, shared by the firmware ISR and
 * the offline tools so both run the same code:
 *
 *   motor current, motor increment -> hd_slow (T_cur, its variance)
 *   output angle increment -> hd_track (velocity, acceleration)
 *   -> hd_expected (T_exp = model + feed-forward + T_cur) -> hd_kf_step
 *   -> filtered torque
 *
 * hd_pipeline_sample is that whole path for one sample: the firmware's tick
 * calls it, and hd_pipeline_run calls it per element of whole arrays (the
 * tools call that once through ctypes), so a log replayed by `hdsense
 * analyze` goes through exactly what the firmware runs.  hd_pipeline_step
 * is the path after the current term (T_exp from a given slow torque).
 * Pure: no I/O, no heap, no globals.
 */
#ifndef HD_PIPELINE_H
#define HD_PIPELINE_H

#include <stddef.h>

#include "hd_expected.h"
#include "hd_kf.h"
#include "hd_slow.h"
#include "hd_track.h"

#ifdef __cplusplus
extern "C" {
#endif

typedef struct {
    hd_kf_t kf;
    hd_track_t output_track;        /* tracks the output angle */
    hd_expected_config_t expected;
    float torque_expected_nm;       /* last T_exp */
} hd_pipeline_t;

/* Initialises all three parts; returns HD_KF_OK or the first error
 * (hd_kf_config_check's, HD_KF_ERR_TRACK_BANDWIDTH, HD_KF_ERR_NULL or
 * HD_KF_ERR_EXPECTED_CONFIG). */
hd_kf_err_t hd_pipeline_init(hd_pipeline_t *p, const hd_kf_config_t *kf_cfg,
                     const hd_expected_config_t *expected_cfg,
                     float track_bandwidth_hz);

/* feedforward_var_nm2: the variance of feedforward_nm's error at this
 * sample (hd_kf_input_t.torque_expected_var_nm2; 0 = none). */
void hd_pipeline_step(hd_pipeline_t *p, float torque_meas_nm,
                      float d_motor_angle_rad, float d_output_angle_rad,
                      float feedforward_nm, float feedforward_var_nm2, hd_kf_output_t *out);

/* One sample's inputs. */
typedef struct {
    float torque_meas_nm;
    float d_motor_angle_rad;
    float d_output_angle_rad;
    float feedforward_nm;       /* the controller's expected torque (0: none) */
    float feedforward_var_nm2;  /* the variance of its error (0: none) */
    float motor_current_a;      /* NaN: no reading (no current term) */
} hd_pipeline_in_t;

/* What the slow-torque assembly gave the filter at this sample. */
typedef struct {
    float torque_expected_nm;
    float torque_expected_var_nm2; /* feedforward_var_nm2 + the current term's */
    float current_nm;              /* T_cur (0 without) */
    float output_velocity_rad_s;   /* from the motor increment, hd_slow_output_velocity_rad_s */
} hd_pipeline_slow_t;

/* The whole path for one sample: T_cur from the current estimator *cur
 * (configured by *cc), then hd_pipeline_step with T_ff + T_cur and the sum
 * of the variances.  slow may be NULL. */
void hd_pipeline_sample(hd_pipeline_t *p, hd_slow_current_t *cur,
                        const hd_slow_current_config_t *cc, const hd_pipeline_in_t *in,
                        hd_pipeline_slow_t *slow, hd_kf_output_t *out);

/* Array form.  Inputs of length n (feedforward and its variance may be
 * NULL = 0); every output
 * pointer may be NULL.  Each element goes through hd_pipeline_sample.  status, if given, receives hd_kf_output_t.status per
 * sample.  amplitude_nm, if given, is n x HD_KF_MAX_BLOCKS, row-major: row i,
 * column b is the amplitude of configured block b's prediction used at
 * sample i times its measurement-row entry in that step
 * (hd_kf_block_amplitude_nm before the step, which the step's turn keeps,
 * x hd_kf_block_row after it:
 * at the load of the step, 0 if the block was frozen or is disabled).  The
 * 1 kHz path never computes it. */
typedef struct {
    size_t n;
    const float *torque_meas_nm;
    const float *d_motor_angle_rad;
    const float *d_output_angle_rad;
    const float *feedforward_nm;
    const float *feedforward_var_nm2;
    float *torque_filtered_nm;
    float *ripple_nm;
    float *offset_nm;
    float *innovation_nm;
    float *innovation_var_nm2;
    float *torque_expected_nm;
    float *output_velocity_rad_s;
    float *amplitude_nm;
    unsigned *status;
    /* The current term (all NULL: none): the current per sample (NaN: no
     * reading), its configuration and the estimator's state, which a run
     * continues (zero it before the first). */
    const float *motor_current_a;
    const hd_slow_current_config_t *current;
    hd_slow_current_t *current_state;
    float *torque_expected_var_nm2; /* output: the variance T_exp was given */
} hd_pipeline_io_t;

void hd_pipeline_run(hd_pipeline_t *p, const hd_pipeline_io_t *io);

#ifdef __cplusplus
}
#endif

#endif /* HD_PIPELINE_H */
