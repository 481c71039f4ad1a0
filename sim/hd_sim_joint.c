/* hd_sim_joint: the dynamic simulated joint (equations in hd_sim_joint.h). */
#include "hd_sim_joint.h"

#include <math.h>
#include <stdbool.h>
#include <stdio.h>
#include <string.h>

void hd_sim_joint_default(hd_sim_joint_params_t *p)
{
    /* A size-20 strain-wave gear, N = 100 (40 N m rated class): catalogue
     * stiffness of the middle segment ~1.8e4 N m/rad, input inertia with a
     * small BLDC rotor 5e-5 kg m^2 (0.5 kg m^2 reflected), no-load running
     * torque a few 0.01 N m at the input; mode damping ratio ~5 %. */
    *p = (hd_sim_joint_params_t){
        .ts_s = 1e-3,
        .substeps = 10,
        .gear_ratio = 100.0,
        .motor_inertia_kgm2 = 5e-5,
        .motor_viscous_nm_s_rad = 1e-4,
        .motor_coulomb_nm = 0.03,
        .motor_stribeck_nm = 0.02,
        .motor_stribeck_velocity_rad_s = 5.0,
        .friction_smoothing_rad_s = 0.1,
        .stiffness_nm_rad = 1.8e4,
        .damping_nm_s_rad = 9.5,
        .output_inertia_kgm2 = 0.2,
        .output_viscous_nm_s_rad = 0.05,
        .payload_kg = 2.0,
        .payload_arm_m = 0.4,
        .link_gravity_nm = 5.0,
        .gravity_phase_rad = 0.0,
        .mesh_ripple_nm = 0.3,
        .mesh_ripple_phase_rad = 0.4,
        .gauge_ripple_nm = 1.5,
        .gauge_ripple_phase_rad = 1.1,
        .env = HD_SIM_ENV_FREE,
        .env_position_rad = 0.0,
        .env_stiffness_nm_rad = 0.0,
        .env_damping_nm_s_rad = 0.0,
    };
}

double hd_sim_joint_output_inertia(const hd_sim_joint_params_t *p)
{
    return p->output_inertia_kgm2 + p->payload_kg * p->payload_arm_m * p->payload_arm_m;
}

double hd_sim_joint_gravity_amplitude(const hd_sim_joint_params_t *p)
{
    return p->link_gravity_nm + p->payload_kg * HD_SIM_G_M_S2 * p->payload_arm_m;
}

static bool nonneg(double x)
{
    return isfinite(x) && x >= 0.0;
}

int hd_sim_joint_check(const hd_sim_joint_params_t *p, char *err, size_t err_len)
{
    const char *bad = NULL;
    if (!(isfinite(p->ts_s) && p->ts_s > 0.0)) {
        bad = "ts_s";
    } else if (p->substeps < 1 || p->substeps > 1000) {
        bad = "substeps";
    } else if (!(isfinite(p->gear_ratio) && p->gear_ratio >= 1.0)) {
        bad = "gear_ratio";
    } else if (!(isfinite(p->motor_inertia_kgm2) && p->motor_inertia_kgm2 > 0.0)) {
        bad = "motor_inertia_kgm2";
    } else if (!(isfinite(p->output_inertia_kgm2) && p->output_inertia_kgm2 > 0.0)) {
        bad = "output_inertia_kgm2";
    } else if (!(isfinite(p->friction_smoothing_rad_s) && p->friction_smoothing_rad_s > 0.0) ||
               !(isfinite(p->motor_stribeck_velocity_rad_s) &&
                 p->motor_stribeck_velocity_rad_s > 0.0)) {
        bad = "friction velocities";
    } else if (!(nonneg(p->motor_viscous_nm_s_rad) && nonneg(p->motor_coulomb_nm) &&
                 nonneg(p->motor_stribeck_nm) && nonneg(p->output_viscous_nm_s_rad))) {
        bad = "friction";
    } else if (!(isfinite(p->stiffness_nm_rad) && p->stiffness_nm_rad > 0.0) ||
               !nonneg(p->damping_nm_s_rad)) {
        bad = "stiffness/damping";
    } else if (!(nonneg(p->payload_kg) && nonneg(p->payload_arm_m) &&
                 isfinite(p->link_gravity_nm) && isfinite(p->gravity_phase_rad))) {
        bad = "payload/gravity";
    } else if (!(isfinite(p->mesh_ripple_nm) && isfinite(p->mesh_ripple_phase_rad) &&
                 isfinite(p->gauge_ripple_nm) && isfinite(p->gauge_ripple_phase_rad))) {
        bad = "ripple";
    } else if ((unsigned)p->env > HD_SIM_ENV_SPRING || !isfinite(p->env_position_rad) ||
               !nonneg(p->env_stiffness_nm_rad) || !nonneg(p->env_damping_nm_s_rad)) {
        bad = "environment";
    }
    if (bad != NULL) {
        if (err != NULL && err_len > 0) {
            snprintf(err, err_len, "dynamic joint: bad %s", bad);
        }
        return -1;
    }
    return 0;
}

int hd_sim_joint_init(hd_sim_joint_t *j, const hd_sim_joint_params_t *p, char *err,
                      size_t err_len)
{
    if (hd_sim_joint_check(p, err, err_len) != 0) {
        return -1;
    }
    memset(j, 0, sizeof(*j));
    j->p = *p;
    return 0;
}

/* ------------------------------------------------------------ the forces */

static double twist_rad(const hd_sim_joint_params_t *p, const hd_sim_joint_state_t *x)
{
    return x->motor_angle_rad / p->gear_ratio - x->output_angle_rad;
}

static double mesh_ripple_nm(const hd_sim_joint_params_t *p, const hd_sim_joint_state_t *x)
{
    return p->mesh_ripple_nm * sin(2.0 * x->motor_angle_rad + p->mesh_ripple_phase_rad);
}

static double output_torque_nm(const hd_sim_joint_params_t *p, const hd_sim_joint_state_t *x)
{
    const double rate = x->motor_velocity_rad_s / p->gear_ratio - x->output_velocity_rad_s;
    return p->stiffness_nm_rad * twist_rad(p, x) + p->damping_nm_s_rad * rate +
           mesh_ripple_nm(p, x);
}

static double motor_friction_nm(const hd_sim_joint_params_t *p, double w)
{
    const double r = w / p->motor_stribeck_velocity_rad_s;
    return p->motor_viscous_nm_s_rad * w +
           (p->motor_coulomb_nm + p->motor_stribeck_nm * exp(-r * r)) *
               tanh(w / p->friction_smoothing_rad_s);
}

static double env_torque_nm(const hd_sim_joint_params_t *p, const hd_sim_joint_state_t *x)
{
    const double e = x->output_angle_rad - p->env_position_rad;
    const double t = p->env_stiffness_nm_rad * e + p->env_damping_nm_s_rad * x->output_velocity_rad_s;
    if (p->env == HD_SIM_ENV_SPRING) {
        return t;
    }
    if (p->env == HD_SIM_ENV_WALL && e > 0.0) {
        return fmax(0.0, t);
    }
    return 0.0;
}

static double gravity_nm(const hd_sim_joint_params_t *p, double theta_o)
{
    return hd_sim_joint_gravity_amplitude(p) * sin(theta_o + p->gravity_phase_rad);
}

typedef struct {
    double tm_nm;
    double person_nm;
} inputs_t;

/* d/dt of the state. */
static hd_sim_joint_state_t deriv(const hd_sim_joint_params_t *p, const hd_sim_joint_state_t *x,
                                  const inputs_t *u)
{
    const double tt = output_torque_nm(p, x);
    const double jo = hd_sim_joint_output_inertia(p);
    const double am = (u->tm_nm - motor_friction_nm(p, x->motor_velocity_rad_s) -
                       tt / p->gear_ratio) / p->motor_inertia_kgm2;
    const double ao = (tt - p->output_viscous_nm_s_rad * x->output_velocity_rad_s -
                       gravity_nm(p, x->output_angle_rad) - env_torque_nm(p, x) + u->person_nm) / jo;
    return (hd_sim_joint_state_t){x->motor_velocity_rad_s, am, x->output_velocity_rad_s, ao};
}

static hd_sim_joint_state_t axpy(const hd_sim_joint_state_t *x, double h,
                                 const hd_sim_joint_state_t *d)
{
    return (hd_sim_joint_state_t){x->motor_angle_rad + h * d->motor_angle_rad,
                                  x->motor_velocity_rad_s + h * d->motor_velocity_rad_s,
                                  x->output_angle_rad + h * d->output_angle_rad,
                                  x->output_velocity_rad_s + h * d->output_velocity_rad_s};
}

static void rk4(const hd_sim_joint_params_t *p, hd_sim_joint_state_t *x, double h,
                const inputs_t *u)
{
    const hd_sim_joint_state_t k1 = deriv(p, x, u);
    const hd_sim_joint_state_t x2 = axpy(x, 0.5 * h, &k1);
    const hd_sim_joint_state_t k2 = deriv(p, &x2, u);
    const hd_sim_joint_state_t x3 = axpy(x, 0.5 * h, &k2);
    const hd_sim_joint_state_t k3 = deriv(p, &x3, u);
    const hd_sim_joint_state_t x4 = axpy(x, h, &k3);
    const hd_sim_joint_state_t k4 = deriv(p, &x4, u);
    const hd_sim_joint_state_t s1 = axpy(&k1, 2.0, &k2);
    const hd_sim_joint_state_t s2 = axpy(&s1, 2.0, &k3);
    const hd_sim_joint_state_t sum = axpy(&s2, 1.0, &k4);
    *x = axpy(x, h / 6.0, &sum);
}

void hd_sim_joint_step(hd_sim_joint_t *j, double motor_torque_nm, hd_sim_joint_truth_t *truth)
{
    const hd_sim_joint_params_t *p = &j->p;
    const inputs_t u = {motor_torque_nm, j->person_torque_nm};
    const double h = p->ts_s / (double)p->substeps;
    for (int k = 0; k < p->substeps; k++) {
        rk4(p, &j->x, h, &u);
    }
    j->t_s += p->ts_s;
    if (truth == NULL) {
        return;
    }
    const hd_sim_joint_state_t *x = &j->x;
    *truth = (hd_sim_joint_truth_t){
        .t_s = j->t_s,
        .motor_angle_rad = x->motor_angle_rad,
        .output_angle_rad = x->output_angle_rad,
        .motor_velocity_rad_s = x->motor_velocity_rad_s,
        .output_velocity_rad_s = x->output_velocity_rad_s,
        .motor_torque_nm = motor_torque_nm,
        .person_torque_nm = u.person_nm,
        .output_torque_nm = output_torque_nm(p, x),
        .mesh_ripple_nm = mesh_ripple_nm(p, x),
        .env_torque_nm = env_torque_nm(p, x),
        .gravity_nm = gravity_nm(p, x->output_angle_rad),
    };
    truth->gauge_torque_nm = hd_sim_joint_gauge_torque_nm(j);
}

double hd_sim_joint_gauge_torque_nm(const hd_sim_joint_t *j)
{
    const hd_sim_joint_params_t *p = &j->p;
    return output_torque_nm(p, &j->x) +
           p->gauge_ripple_nm * sin(2.0 * j->x.motor_angle_rad + p->gauge_ripple_phase_rad);
}

double hd_sim_joint_energy(const hd_sim_joint_t *j)
{
    const hd_sim_joint_params_t *p = &j->p;
    const hd_sim_joint_state_t *x = &j->x;
    const double d = twist_rad(p, x);
    const double e = x->output_angle_rad - p->env_position_rad;
    double env = 0.0;
    if (p->env == HD_SIM_ENV_SPRING || (p->env == HD_SIM_ENV_WALL && e > 0.0)) {
        env = 0.5 * p->env_stiffness_nm_rad * e * e;
    }
    return 0.5 * p->motor_inertia_kgm2 * x->motor_velocity_rad_s * x->motor_velocity_rad_s +
           0.5 * hd_sim_joint_output_inertia(p) * x->output_velocity_rad_s *
               x->output_velocity_rad_s +
           0.5 * p->stiffness_nm_rad * d * d +
           hd_sim_joint_gravity_amplitude(p) * (1.0 - cos(x->output_angle_rad + p->gravity_phase_rad)) +
           env;
}
