/*
 * hd_bridge: the rosette Wheatstone bridge of the built-in torque sensor,
 * Taghirad, Helmy & Belanger (1997), equations 1-4.
 *
 * Four rosettes sit on the flexspline diaphragm at nominal circumferential
 * positions phi_k = k * pi/2 (k = 0..3), each displaced by a placement error
 * delta_k.  The two perpendicular gauges of rosette k see
 *
 *   eps_a - eps_b = 2 eps_t + Psi0 sin(2 (beta - phi_k - delta_k))     (eqs 2, 3)
 *
 * where eps_t = strain_per_nm * torque is the torsional strain and beta is
 * the wave-generator angle relative to the gauges (the ellipse's major axis
 * moves with the wave generator and is two-fold symmetric, hence 2 beta).
 * The eight gauges form one full bridge, so the output averages the four
 * rosettes:
 *
 *   E_out = (K/8) sum_k (eps_a - eps_b)_k E_sup
 *         = K eps_t E_sup + (K E_sup Psi0 / 8) sum_k sin(2 beta - k pi - 2 delta_k)
 *
 * With delta_k = 0 the sum is sin 2b - sin 2b + sin 2b - sin 2b = 0 and
 * E_out = K eps_t E_sup, equation 4.  With small errors the residual is, to
 * first order in delta,
 *
 *   E_out - K eps_t E_sup ~= -(K E_sup Psi0 / 4) S cos(2 beta),
 *   S = delta_0 - delta_1 + delta_2 - delta_3,
 *
 * a line at twice the wave-generator frequency: the residual 2x ripple of
 * section II, indistinguishable in frequency from gear-meshing ripple.
 * The amplifier multiplies E_out by amp_gain.
 *
 * Host-side model (also used by the calibration campaign simulator); float
 * interface, double inside.
 */
#ifndef HD_BRIDGE_H
#define HD_BRIDGE_H

#ifdef __cplusplus
extern "C" {
#endif

#define HD_BRIDGE_ROSETTES 4

/* Nominal sensor gain at the amplifier output (Table I of the paper). */
#define HD_BRIDGE_NOMINAL_NM_PER_V 6.60f

typedef struct {
    float gauge_factor;            /* K, default 2.0 */
    float supply_v;                /* E_sup, default 10 V */
    float amp_gain;                /* default 1000 */
    float strain_per_nm;           /* torsional strain eps_t per N m; default
                                      1/(6.60*K*E*G) so the nominal sensor gain
                                      is 6.60 N m/V at the amplifier output */
    float psi0;                    /* elliptical modulation amplitude (strain) */
    float placement_error_rad[HD_BRIDGE_ROSETTES]; /* circumferential placement error of
                                      each rosette; 0 = ideal (modulation cancels) */
} hd_bridge_config_t;

/* K = 2, E = 10 V, G = 1000, 6.60 N m/V, psi0 = HD_BRIDGE_DEFAULT_PSI0
 * (a modulation worth ~5 N m per rosette), ideal placement. */
#define HD_BRIDGE_DEFAULT_PSI0 3.8e-5f
void hd_bridge_config_default(hd_bridge_config_t *c);

/* Amplified bridge output [V] for a transmitted torque and wave-generator
 * angle.  NULL config or non-finite inputs give NaN. */
float hd_bridge_output_v(const hd_bridge_config_t *c, float torque_nm, float wg_angle_rad);

/* Sensor gain at the amplifier output [N m / V] = 1/(strain_per_nm*K*E*G);
 * NaN if any factor is zero or not finite. */
float hd_bridge_gain_nm_per_v(const hd_bridge_config_t *c);

/* First-order amplitude of the residual 2x line [V at the amplifier output]:
 * K E G Psi0 |S| / 4 (see above). */
float hd_bridge_residual_2x_v(const hd_bridge_config_t *c);

#ifdef __cplusplus
}
#endif

#endif /* HD_BRIDGE_H */
