/*
 * hd_expected: the paper's crude expected-torque model (section IV), extended.
 *
 *   T_exp = J * acc_out + b * vel_out + Fc * vel_out / (|vel_out| + v_eps) + T_ff
 *
 * J: load inertia at the output; b: viscous; Fc: Coulomb friction with its
 * sign function smoothed over v_eps so T_exp stays continuous through
 * reversals; T_ff: optional feed-forward from the controller.  All
 * coefficients default to zero (T_exp = T_ff).  The filter needs only a rough
 * T_exp: what it misses enters R (or the offset state), not the ripple.
 *
 * Motor current (optional second source of slow torque, docs/design/slow-torque.md):
 *
 *   T_cur = k_i i - J_r acc_out - b_r vel_out - Fc_r vel_out / (|vel_out| + v_eps)
 *
 * k_i = N eta kt turns the motor's torque-producing current into output
 * torque; J_r, b_r, Fc_r are what the drive between the current and the
 * sensor absorbs (rotor and wave-generator inertia N^2 J_m, motor-side
 * friction), referred to the output.  The caller adds T_cur to T_ff (it has
 * its own configuration so hd_expected_config_t keeps its layout).
 *
 * A gear passes power with one efficiency when the motor drives the load
 * (eta) and another when the load drives the motor (eta_b).  k_b = N kt /
 * eta_b is the torque per amp of the second case: T_cur above is scaled by
 * k_b / k_i where it opposes the motion (T_cur vel < 0), blended in over
 * v_eps like the Coulomb sign; at standstill the motor holds the load (k_i).
 * k_b = 0: one efficiency.
 */
#ifndef HD_EXPECTED_H
#define HD_EXPECTED_H

#include "hd_filter_err.h"

#ifdef __cplusplus
extern "C" {
#endif

typedef struct {
    float inertia_kgm2;          /* J [kg m^2] at the output */
    float viscous_nm_s_rad;      /* b [N m s / rad] */
    float coulomb_nm;            /* Fc [N m] */
    float coulomb_vel_eps_rad_s; /* v_eps [rad/s], > 0; default 0.01 */
} hd_expected_config_t;

/* The motor-current term; all zero = no current term. */
typedef struct {
    float nm_per_a;          /* k_i = N eta kt [N m per A], output torque per motor amp */
    float coulomb_nm;        /* Fc_r [N m] */
    float viscous_nm_s_rad;  /* b_r [N m s / rad] */
    float inertia_kgm2;      /* J_r [kg m^2] */
    float backdrive_nm_per_a; /* k_b = N kt / eta_b [N m per A] when the load drives
                                 the motor; 0 = k_i (one efficiency) */
    float error_nm;          /* RMS error of the term beyond its lag (the model's fit
                                residual, current noise) [N m]; hd_slow adds its
                                square to the variance T_exp is given */
} hd_expected_current_config_t;

void hd_expected_config_default(hd_expected_config_t *cfg);

/* Returns HD_KF_OK if every field is finite, J, b, Fc >= 0 and v_eps > 0;
 * HD_KF_ERR_NULL for NULL, else HD_KF_ERR_EXPECTED_CONFIG. */
hd_kf_err_t hd_expected_config_check(const hd_expected_config_t *cfg);

float hd_expected_torque_nm(const hd_expected_config_t *cfg,
                            float vel_out_rad_s, float acc_out_rad_s2,
                            float feedforward_nm);

/* The least product of the two efficiencies (driving x driven) a model may
 * imply: below it no gear transmits. */
#define HD_EXPECTED_MIN_EFFICIENCY_PRODUCT 0.01f

/* HD_KF_OK if every field (error_nm too) is finite and >= 0 and, with both gains set, the
 * efficiencies they imply are physical: nm_per_a / backdrive_nm_per_a =
 * eta x eta_b in [HD_EXPECTED_MIN_EFFICIENCY_PRODUCT, 1] (backdrive at
 * least nm_per_a); HD_KF_ERR_NULL for NULL, else
 * HD_KF_ERR_EXPECTED_CONFIG. */
hd_kf_err_t hd_expected_current_check(const hd_expected_current_config_t *cur);

/* T_cur above (with k_b where it applies); the Coulomb sign and the
 * direction of power flow are smoothed with cfg's v_eps. */
float hd_expected_current_nm(const hd_expected_current_config_t *cur,
                             const hd_expected_config_t *cfg, float motor_current_a,
                             float vel_out_rad_s, float acc_out_rad_s2);

#ifdef __cplusplus
}
#endif

#endif /* HD_EXPECTED_H */
