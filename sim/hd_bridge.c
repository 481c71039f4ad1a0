#include "hd_bridge.h"

#include <math.h>
#include <stddef.h>

#define HD_PI 3.14159265358979323846

void hd_bridge_config_default(hd_bridge_config_t *c)
{
    if (c == NULL) {
        return;
    }
    c->gauge_factor = 2.0f;
    c->supply_v = 10.0f;
    c->amp_gain = 1000.0f;
    c->strain_per_nm = (float)(1.0 / (6.60 * 2.0 * 10.0 * 1000.0));
    c->psi0 = HD_BRIDGE_DEFAULT_PSI0;
    for (int k = 0; k < HD_BRIDGE_ROSETTES; k++) {
        c->placement_error_rad[k] = 0.0f;
    }
}

/* K * E_sup * G: volts at the amplifier output per unit strain. */
static double volts_per_strain(const hd_bridge_config_t *c)
{
    return (double)c->gauge_factor * (double)c->supply_v * (double)c->amp_gain;
}

float hd_bridge_output_v(const hd_bridge_config_t *c, float torque_nm, float wg_angle_rad)
{
    if (c == NULL || !isfinite(torque_nm) || !isfinite(wg_angle_rad)) {
        return NAN;
    }
    const double eps_t = (double)c->strain_per_nm * (double)torque_nm;
    const double two_beta = 2.0 * (double)wg_angle_rad;
    /* Sum of the four rosette differences (eqs 2, 3), each 2 eps_t + modulation. */
    double diff_sum = 0.0;
    for (int k = 0; k < HD_BRIDGE_ROSETTES; k++) {
        const double phi_k = (double)k * (HD_PI / 2.0) + (double)c->placement_error_rad[k];
        diff_sum += 2.0 * eps_t + (double)c->psi0 * sin(two_beta - 2.0 * phi_k);
    }
    /* Full bridge of 8 gauges: E_out = K/8 * sum * E_sup (eq 4 generalised). */
    return (float)(volts_per_strain(c) * diff_sum / 8.0);
}

float hd_bridge_gain_nm_per_v(const hd_bridge_config_t *c)
{
    if (c == NULL) {
        return NAN;
    }
    const double v_per_nm = volts_per_strain(c) * (double)c->strain_per_nm;
    if (!isfinite(v_per_nm) || v_per_nm == 0.0) {
        return NAN;
    }
    return (float)(1.0 / v_per_nm);
}

float hd_bridge_residual_2x_v(const hd_bridge_config_t *c)
{
    if (c == NULL) {
        return NAN;
    }
    double s = 0.0;
    for (int k = 0; k < HD_BRIDGE_ROSETTES; k++) {
        s += ((k % 2) == 0 ? 1.0 : -1.0) * (double)c->placement_error_rad[k];
    }
    return (float)(volts_per_strain(c) * (double)c->psi0 * fabs(s) / 4.0);
}
