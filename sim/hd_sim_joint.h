/*
 * hd_sim_joint: the dynamic simulated joint (host only; issue 23), beside
 * the kinematic plant of hd_sim_plant (whose motor speed is prescribed).
 * Here the drive's motor torque is the input and the motion follows:
 *
 *   twist     d   = theta_m / N - theta_o             (output side, rad)
 *   T_t           = K d + D d' + A_mesh sin(2 theta_m + phi_mesh)
 *   J_m theta_m'' = T_m - f_m(omega_m) - T_t / N
 *   J_o theta_o'' = T_t - b_o omega_o - G sin(theta_o + phi_g) - T_env + T_person
 *   f_m(w)        = b_m w + (Fc + Fs exp(-(w/ws)^2)) tanh(w / eps)
 *   J_o           = J_link + m l^2,   G = G_link + m g l
 *   T_env         = free: 0;  spring: K_e (theta_o - q_e) + D_e omega_o;
 *                   wall:  max(0, K_e (theta_o - q_e) + D_e omega_o) once
 *                          theta_o > q_e (it pushes, never pulls)
 *
 * T_t is the true output torque: what the flexspline transmits, including
 * the real meshing ripple (a torque in the transmission at 2x the motor
 * angle: it moves the output).  The gauge reads T_t plus the sensing
 * artifact A_gauge sin(2 theta_m + phi_gauge), which exists on the gauge only
 * and moves nothing.  tanh(w / eps) is sgn(w) made smooth enough for the
 * integrator (eps = 0.1 rad/s at the motor: 1 mrad/s at the output).
 * Integration: classical RK4, `substeps` steps per tick, the motor and
 * person torques held over the tick (zero-order hold, as a drive does).
 * Parameters of a 40 N m class drive: hd_sim_joint_default and docs/reference/sim.md.
 */
#ifndef HD_SIM_JOINT_H
#define HD_SIM_JOINT_H

#include <stddef.h>

#ifdef __cplusplus
extern "C" {
#endif

typedef enum {
    HD_SIM_ENV_FREE = 0,
    HD_SIM_ENV_WALL = 1,
    HD_SIM_ENV_SPRING = 2,
} hd_sim_env_t;

typedef struct {
    double ts_s;
    int substeps;
    double gear_ratio;                  /* N */
    double motor_inertia_kgm2;          /* J_m: rotor + wave generator */
    double motor_viscous_nm_s_rad;      /* b_m */
    double motor_coulomb_nm;            /* Fc (motor side) */
    double motor_stribeck_nm;           /* Fs: break-away above Fc (motor side) */
    double motor_stribeck_velocity_rad_s; /* ws */
    double friction_smoothing_rad_s;    /* eps */
    double stiffness_nm_rad;            /* K (flexspline, output side) */
    double damping_nm_s_rad;            /* D */
    double output_inertia_kgm2;         /* J_link */
    double output_viscous_nm_s_rad;     /* b_o (output bearing) */
    double payload_kg;                  /* m, a point mass at payload_arm_m */
    double payload_arm_m;               /* l */
    double link_gravity_nm;             /* G_link: the link's own m g l_c */
    double gravity_phase_rad;           /* phi_g (0: hanging down at theta_o = 0) */
    double mesh_ripple_nm;              /* A_mesh: real, in the transmission */
    double mesh_ripple_phase_rad;
    double gauge_ripple_nm;             /* A_gauge: sensing artifact, gauge only */
    double gauge_ripple_phase_rad;
    hd_sim_env_t env;
    double env_position_rad;            /* q_e */
    double env_stiffness_nm_rad;        /* K_e */
    double env_damping_nm_s_rad;        /* D_e */
} hd_sim_joint_params_t;

typedef struct {
    double motor_angle_rad;
    double motor_velocity_rad_s;
    double output_angle_rad;
    double output_velocity_rad_s;
} hd_sim_joint_state_t;

/* The logged truth of one tick, at its end. */
typedef struct {
    double t_s;
    double motor_angle_rad;
    double output_angle_rad;
    double motor_velocity_rad_s;
    double output_velocity_rad_s;
    double motor_torque_nm;     /* T_m the drive applied over the tick */
    double person_torque_nm;    /* T_person over the tick */
    double output_torque_nm;    /* T_t: the true output torque */
    double mesh_ripple_nm;      /* its meshing part */
    double gauge_torque_nm;     /* T_t + the sensing artifact: what the gauge sees */
    double env_torque_nm;       /* T_env */
    double gravity_nm;          /* G sin(theta_o + phi_g) */
} hd_sim_joint_truth_t;

typedef struct {
    hd_sim_joint_params_t p;
    hd_sim_joint_state_t x;
    double t_s;
    double person_torque_nm;    /* set between ticks: a person back-driving the output */
} hd_sim_joint_t;

#define HD_SIM_G_M_S2 9.80665

/* A 40 N m class joint (size-20 strain-wave gear, N = 100; docs/reference/sim.md). */
void hd_sim_joint_default(hd_sim_joint_params_t *p);

/* 0, or -1 with the first bad parameter named in err. */
int hd_sim_joint_check(const hd_sim_joint_params_t *p, char *err, size_t err_len);

/* Checks p; at rest, no twist, angles 0.  Returns 0 or -1 (+ err). */
int hd_sim_joint_init(hd_sim_joint_t *j, const hd_sim_joint_params_t *p, char *err,
                      size_t err_len);

/* One tick under the motor torque (motor side, N m); fills *truth. */
void hd_sim_joint_step(hd_sim_joint_t *j, double motor_torque_nm, hd_sim_joint_truth_t *truth);

/* What the gauge sees now: the output torque plus the sensing artifact. */
double hd_sim_joint_gauge_torque_nm(const hd_sim_joint_t *j);

/* Kinetic + elastic (flexspline, spring or wall) + gravity potential: what
 * is conserved with no friction, damping, ripple or external torque. */
double hd_sim_joint_energy(const hd_sim_joint_t *j);

/* Total output inertia J_link + m l^2 and gravity amplitude G. */
double hd_sim_joint_output_inertia(const hd_sim_joint_params_t *p);
double hd_sim_joint_gravity_amplitude(const hd_sim_joint_params_t *p);

#ifdef __cplusplus
}
#endif

#endif /* HD_SIM_JOINT_H */
