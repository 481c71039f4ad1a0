/*
 * hd_sim_plant: the simulated joint, one sample per call.
 *
 * Truth (ripple-free transmitted torque at the flexspline):
 *   theta_m(t)  = motor_angle0 + integral of the motor speed profile (exact)
 *   theta_o     = theta_m / N,  omega_o = omega_m / N,  alpha_o = alpha_m / N
 *   T_true      = J alpha_o + b omega_o + Fc sgn(omega_o)
 *                 + Fs exp(-(omega_o/ws)^2) sgn(omega_o) + T_load(t)
 *                 + m g l(t) sin(theta_o + phase)          [arm link under gravity]
 * Motor current and the controller's feed-forward: docs/reference/sim.md.
 * What the sensor adds (ripple_true = measured - truth, before noise):
 *   T_sensed    = T_true + sum_lines (1 + c |T_true|) A sin(order theta + phase)
 *                 + offset(t)    [c applies to motor and output lines only]
 *   v_clean     = bridge(T_sensed, beta = theta_m) + bridge_offset_v
 *   v           = bridge(T_sensed + n_nm, beta) + bridge_offset_v + n_v
 *   counts      = clip(round(v / lsb)),  lsb = 2 range / 2^bits
 * Encoders: floor(theta cpr / 2 pi) as uint32 (wraps).
 */
#ifndef HD_SIM_PLANT_H
#define HD_SIM_PLANT_H

#include <stdbool.h>
#include <stdint.h>

#include "hd_sim_scenario.h"

#ifdef __cplusplus
extern "C" {
#endif

typedef struct {
    uint64_t index;
    double t_s;
    double motor_angle_rad;
    double output_angle_rad;
    double motor_velocity_rad_s;
    double output_velocity_rad_s;
    double output_accel_rad_s2;
    double load_torque_nm;      /* external load at t: profile + sines */
    double gravity_nm;          /* arm link gravity torque at t (part of the truth) */
    double torque_true_nm;      /* ripple-free transmitted torque (ground truth) */
    double ripple_true_nm;      /* measured - truth before noise (incl. bridge residual, offset) */
    double bridge_v;            /* amplified bridge output with noise, before the ADC */
    double torque_nm;           /* bridge_counts through the nominal calibration */
    int32_t bridge_counts;
    bool saturated;
    uint32_t motor_counts;
    uint32_t output_counts;
    bool has_output;
    bool encoder_fault;
    double feedforward_nm;      /* the controller's model (NaN without feed-forward) */
    bool feedforward_sent;      /* a frame goes out this sample */
    double motor_current_a;     /* measured (NaN without a current channel) */
} hd_sim_sample_t;

/* Nominal calibration and drive constants for the firmware's defaults. */
typedef struct {
    double gain_nm_per_v;       /* torque = (counts * adc_v_per_count - offset_v) * gain */
    double offset_v;
    double adc_v_per_count;
    int adc_bits;
    double gear_ratio;
    uint32_t motor_cpr;
    uint32_t output_cpr;        /* 0 = none */
    double ts_s;
    double load_inertia_kgm2;
    double viscous_nm_s_rad;
    double coulomb_nm;
    double motor_kt_nm_per_a;   /* datasheet (not the plant's true) torque constant */
} hd_sim_nominal_t;

typedef struct {
    hd_sim_scenario_t sc;
    uint64_t n_samples;
    uint64_t next;              /* index of the next sample */
    double seg_angle_rad[HD_SIM_MAX_POINTS]; /* motor angle at each speed breakpoint */
    double offset_walk_nm;
    uint64_t rng[4];            /* xoshiro256** */
    bool has_spare;
    double spare;
    hd_sim_nominal_t nominal;
} hd_sim_plant_t;

/* Validates the scenario and resets to sample 0.  Returns 0 or -1 + err. */
int hd_sim_plant_init(hd_sim_plant_t *p, const hd_sim_scenario_t *sc, char *err, size_t err_len);

/* Produces the next sample; returns 0, or 1 when the scenario has ended. */
int hd_sim_plant_next(hd_sim_plant_t *p, hd_sim_sample_t *out);

void hd_sim_nominal(const hd_sim_scenario_t *sc, hd_sim_nominal_t *out);

/* Closed-form motor kinematics at any t (no noise, no state). */
void hd_sim_motor_kinematics(const hd_sim_plant_t *p, double t_s, double *angle_rad,
                             double *velocity_rad_s, double *accel_rad_s2);

#ifdef __cplusplus
}
#endif

#endif /* HD_SIM_PLANT_H */
