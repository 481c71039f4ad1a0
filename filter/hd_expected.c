/* hd_expected: see hd_expected.h. */
#include "hd_expected.h"

#include <stddef.h>

#include "hd_float.h"

#define DEFAULT_VEL_EPS_RAD_S 0.01f

void hd_expected_config_default(hd_expected_config_t *cfg)
{
    cfg->inertia_kgm2 = 0.0f;
    cfg->viscous_nm_s_rad = 0.0f;
    cfg->coulomb_nm = 0.0f;
    cfg->coulomb_vel_eps_rad_s = DEFAULT_VEL_EPS_RAD_S;
}

hd_kf_err_t hd_expected_config_check(const hd_expected_config_t *cfg)
{
    if (cfg == NULL) {
        return HD_KF_ERR_NULL;
    }
    if (!is_finite(cfg->inertia_kgm2) || cfg->inertia_kgm2 < 0.0f ||
        !is_finite(cfg->viscous_nm_s_rad) || cfg->viscous_nm_s_rad < 0.0f ||
        !is_finite(cfg->coulomb_nm) || cfg->coulomb_nm < 0.0f ||
        !is_finite(cfg->coulomb_vel_eps_rad_s) || cfg->coulomb_vel_eps_rad_s <= 0.0f) {
        return HD_KF_ERR_EXPECTED_CONFIG;
    }
    return HD_KF_OK;
}

static float smooth_sign(const hd_expected_config_t *cfg, float vel_out_rad_s)
{
    return smooth_sign_f(vel_out_rad_s, cfg->coulomb_vel_eps_rad_s);
}

float hd_expected_torque_nm(const hd_expected_config_t *cfg,
                            float vel_out_rad_s, float acc_out_rad_s2,
                            float feedforward_nm)
{
    return cfg->inertia_kgm2 * acc_out_rad_s2 + cfg->viscous_nm_s_rad * vel_out_rad_s +
           cfg->coulomb_nm * smooth_sign(cfg, vel_out_rad_s) + feedforward_nm;
}

hd_kf_err_t hd_expected_current_check(const hd_expected_current_config_t *cur)
{
    if (cur == NULL) {
        return HD_KF_ERR_NULL;
    }
    const float v[6] = {cur->nm_per_a,     cur->coulomb_nm,         cur->viscous_nm_s_rad,
                        cur->inertia_kgm2, cur->backdrive_nm_per_a, cur->error_nm};
    for (unsigned i = 0; i < 6u; i++) {
        if (!is_finite(v[i]) || v[i] < 0.0f) {
            return HD_KF_ERR_EXPECTED_CONFIG;
        }
    }
    /* k_i = N kt eta and k_b = N kt / eta_b: k_i / k_b = eta eta_b must lie
     * in [HD_EXPECTED_MIN_EFFICIENCY_PRODUCT, 1] */
    if (cur->backdrive_nm_per_a > 0.0f && cur->nm_per_a > 0.0f &&
        (cur->backdrive_nm_per_a < cur->nm_per_a ||
         cur->nm_per_a < HD_EXPECTED_MIN_EFFICIENCY_PRODUCT * cur->backdrive_nm_per_a)) {
        return HD_KF_ERR_EXPECTED_CONFIG;
    }
    return HD_KF_OK;
}

float hd_expected_current_nm(const hd_expected_current_config_t *cur,
                             const hd_expected_config_t *cfg, float motor_current_a,
                             float vel_out_rad_s, float acc_out_rad_s2)
{
    const float sign_vel = smooth_sign(cfg, vel_out_rad_s);
    const float driving = cur->nm_per_a * motor_current_a - cur->inertia_kgm2 * acc_out_rad_s2 -
                          cur->viscous_nm_s_rad * vel_out_rad_s - cur->coulomb_nm * sign_vel;
    if (!(cur->backdrive_nm_per_a > 0.0f && cur->nm_per_a > 0.0f)) {
        return driving;
    }
    /* share of the load driving the motor: 1 where the torque opposes the
     * motion, 0 where it goes with it and at standstill (the motor holds
     * the load) */
    const float with_motion = driving >= 0.0f ? sign_vel : -sign_vel;
    const float backdriven = with_motion < 0.0f ? -with_motion : 0.0f;
    const float ratio = cur->backdrive_nm_per_a / cur->nm_per_a;
    return driving * (1.0f + backdriven * (ratio - 1.0f));
}
