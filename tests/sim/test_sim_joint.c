/*
 * hd_sim_joint (the dynamic simulated joint) against closed forms:
 *   - the flexspline mode of the free two-mass joint rings at
 *       f = sqrt(K (1 / (J_m N^2) + 1 / J_o)) / 2 pi;
 *   - under a constant motor torque against a spring the joint settles where
 *       K_e theta_o + G sin(theta_o) = N T_m,  twist = N T_m / K
 *     (root found here by Newton's method, independently of the integrator);
 *   - with no friction, damping, ripple or external torque the energy
 *     (kinetic + flexspline + spring + gravity) is constant;
 *   - the gauge artifact moves nothing (bit-identical motion), the meshing
 *     ripple moves the output;
 *   - a wall pushes, never pulls.
 */
#include <math.h>
#include <stdbool.h>
#include <stdio.h>

#include "hd_sim_joint.h"
#include "unity.h"

#define PI_D 3.14159265358979323846

void setUp(void) {}
void tearDown(void) {}

/* The default joint without dry friction (which would leave a rest point
 * undetermined), meshing ripple and, unless kept, gravity. */
static hd_sim_joint_params_t smooth(bool keep_gravity)
{
    hd_sim_joint_params_t p;
    hd_sim_joint_default(&p);
    p.motor_coulomb_nm = 0.0;
    p.motor_stribeck_nm = 0.0;
    p.mesh_ripple_nm = 0.0;
    if (!keep_gravity) {
        p.link_gravity_nm = 0.0;
        p.payload_kg = 0.0;
    }
    return p;
}

/* ... and without any loss or ripple: a conservative system. */
static hd_sim_joint_params_t lossless(void)
{
    hd_sim_joint_params_t p = smooth(false);
    p.motor_viscous_nm_s_rad = 0.0;
    p.damping_nm_s_rad = 0.0;
    p.output_viscous_nm_s_rad = 0.0;
    p.gauge_ripple_nm = 0.0;
    return p;
}

static void test_defaults_valid_and_checked(void)
{
    hd_sim_joint_params_t p;
    hd_sim_joint_default(&p);
    char err[80];
    TEST_ASSERT_EQUAL_INT(0, hd_sim_joint_check(&p, err, sizeof err));
    p.stiffness_nm_rad = 0.0;
    TEST_ASSERT_EQUAL_INT(-1, hd_sim_joint_check(&p, err, sizeof err));
    hd_sim_joint_default(&p);
    p.motor_inertia_kgm2 = NAN;
    TEST_ASSERT_EQUAL_INT(-1, hd_sim_joint_check(&p, err, sizeof err));
    hd_sim_joint_default(&p);
    p.substeps = 0;
    TEST_ASSERT_EQUAL_INT(-1, hd_sim_joint_check(&p, err, sizeof err));
}

static void test_flexspline_mode_frequency(void)
{
    hd_sim_joint_params_t p = lossless();
    hd_sim_joint_t j;
    TEST_ASSERT_EQUAL_INT(0, hd_sim_joint_init(&j, &p, NULL, 0));
    j.x.output_angle_rad = -1e-3; /* 1 mrad of twist, released */
    const double n2 = p.gear_ratio * p.gear_ratio;
    const double f_expect = sqrt(p.stiffness_nm_rad * (1.0 / (p.motor_inertia_kgm2 * n2) +
                                                       1.0 / p.output_inertia_kgm2)) / (2.0 * PI_D);
    double prev = 1e-3, first = -1.0, last = -1.0;
    int crossings = 0;
    for (int k = 1; k <= 2000; k++) {
        hd_sim_joint_truth_t t;
        hd_sim_joint_step(&j, 0.0, &t);
        const double d = t.motor_angle_rad / p.gear_ratio - t.output_angle_rad;
        if (prev < 0.0 && d >= 0.0) { /* upward crossing, interpolated */
            const double tc = (k - 1 + prev / (prev - d)) * p.ts_s;
            if (first < 0.0) {
                first = tc;
            } else {
                crossings++;
            }
            last = tc;
        }
        prev = d;
    }
    const double f = crossings / (last - first);
    printf("sim_joint: flexspline mode %.3f Hz, closed form %.3f Hz\n", f, f_expect);
    TEST_ASSERT_DOUBLE_WITHIN(1e-3 * f_expect, f_expect, f);
}

/* Newton on K_e q + G sin q - T = 0. */
static double spring_equilibrium(double ke, double g, double t)
{
    double q = t / ke;
    for (int i = 0; i < 50; i++) {
        q -= (ke * q + g * sin(q) - t) / (ke + g * cos(q));
    }
    return q;
}

static void test_static_deflection_against_spring_and_gravity(void)
{
    hd_sim_joint_params_t p = smooth(true); /* gravity of the default payload and link */
    p.env = HD_SIM_ENV_SPRING;
    p.env_stiffness_nm_rad = 200.0;
    p.env_damping_nm_s_rad = 20.0;
    hd_sim_joint_t j;
    TEST_ASSERT_EQUAL_INT(0, hd_sim_joint_init(&j, &p, NULL, 0));
    const double tm = 0.2; /* 20 N m at the output */
    hd_sim_joint_truth_t t;
    for (int k = 0; k < 8000; k++) {
        hd_sim_joint_step(&j, tm, &t);
    }
    const double g = hd_sim_joint_gravity_amplitude(&p);
    const double q = spring_equilibrium(p.env_stiffness_nm_rad, g, p.gear_ratio * tm);
    const double twist = t.motor_angle_rad / p.gear_ratio - t.output_angle_rad;
    printf("sim_joint: rest at %.6f rad (closed form %.6f), twist %.4e rad (%.4e)\n",
           t.output_angle_rad, q, twist, p.gear_ratio * tm / p.stiffness_nm_rad);
    TEST_ASSERT_DOUBLE_WITHIN(1e-6, q, t.output_angle_rad);
    TEST_ASSERT_DOUBLE_WITHIN(1e-8, p.gear_ratio * tm / p.stiffness_nm_rad, twist);
    TEST_ASSERT_DOUBLE_WITHIN(1e-4, p.gear_ratio * tm, t.output_torque_nm);
}

static void test_energy_conserved_without_losses(void)
{
    hd_sim_joint_params_t p = lossless();
    p.link_gravity_nm = 8.0; /* gravity and a spring store energy too */
    p.env = HD_SIM_ENV_SPRING;
    p.env_stiffness_nm_rad = 50.0;
    hd_sim_joint_t j;
    TEST_ASSERT_EQUAL_INT(0, hd_sim_joint_init(&j, &p, NULL, 0));
    j.x.output_angle_rad = 0.5;
    j.x.motor_velocity_rad_s = 80.0;
    j.x.motor_angle_rad = 0.5 * p.gear_ratio + 0.05;
    const double e0 = hd_sim_joint_energy(&j);
    double worst = 0.0;
    for (int k = 0; k < 3000; k++) {
        hd_sim_joint_step(&j, 0.0, NULL);
        worst = fmax(worst, fabs(hd_sim_joint_energy(&j) - e0));
    }
    printf("sim_joint: energy %.4f J, worst drift %.3e J over 3 s\n", e0, worst);
    TEST_ASSERT_DOUBLE_WITHIN(1e-7 * e0, 0.0, worst);
}

/* Driven by the same torque, with and without each ripple. */
static void run_ripple(double mesh, double gauge, hd_sim_joint_truth_t *log, int n)
{
    hd_sim_joint_params_t p;
    hd_sim_joint_default(&p);
    p.mesh_ripple_nm = mesh;
    p.gauge_ripple_nm = gauge;
    hd_sim_joint_t j;
    TEST_ASSERT_EQUAL_INT(0, hd_sim_joint_init(&j, &p, NULL, 0));
    for (int k = 0; k < n; k++) {
        hd_sim_joint_step(&j, 0.3, &log[k]);
    }
}

#define RIPPLE_N 1500
static hd_sim_joint_truth_t log_none[RIPPLE_N], log_gauge[RIPPLE_N], log_mesh[RIPPLE_N];

static void test_gauge_artifact_moves_nothing_mesh_ripple_does(void)
{
    hd_sim_joint_params_t p;
    hd_sim_joint_default(&p);
    run_ripple(0.0, 0.0, log_none, RIPPLE_N);
    run_ripple(0.0, p.gauge_ripple_nm, log_gauge, RIPPLE_N);
    run_ripple(p.mesh_ripple_nm, 0.0, log_mesh, RIPPLE_N);
    double gauge_err = 0.0, moved = 0.0, mesh_torque = 0.0;
    for (int k = 0; k < RIPPLE_N; k++) {
        TEST_ASSERT_EQUAL_MEMORY(&log_none[k].output_angle_rad, &log_gauge[k].output_angle_rad,
                                 sizeof(double));
        TEST_ASSERT_EQUAL_MEMORY(&log_none[k].output_torque_nm, &log_gauge[k].output_torque_nm,
                                 sizeof(double));
        const double art = p.gauge_ripple_nm *
                           sin(2.0 * log_gauge[k].motor_angle_rad + p.gauge_ripple_phase_rad);
        gauge_err = fmax(gauge_err, fabs(log_gauge[k].gauge_torque_nm -
                                         log_gauge[k].output_torque_nm - art));
        moved = fmax(moved, fabs(log_mesh[k].output_angle_rad - log_none[k].output_angle_rad));
        mesh_torque = fmax(mesh_torque, fabs(log_mesh[k].mesh_ripple_nm));
    }
    printf("sim_joint: gauge artifact error %.2e N m; the mesh ripple moved the output by up to "
           "%.2e rad (peak %.3f N m)\n", gauge_err, moved, mesh_torque);
    TEST_ASSERT_DOUBLE_WITHIN(1e-12, 0.0, gauge_err);
    TEST_ASSERT_TRUE(moved > 1e-6);
    TEST_ASSERT_DOUBLE_WITHIN(1e-3, p.mesh_ripple_nm, mesh_torque);
}

static void test_wall_pushes_never_pulls(void)
{
    hd_sim_joint_params_t p = smooth(false);
    p.env = HD_SIM_ENV_WALL;
    p.env_position_rad = 0.05;
    p.env_stiffness_nm_rad = 2e4;
    p.env_damping_nm_s_rad = 30.0;
    hd_sim_joint_t j;
    TEST_ASSERT_EQUAL_INT(0, hd_sim_joint_init(&j, &p, NULL, 0));
    hd_sim_joint_truth_t t;
    double least_env = 0.0;
    for (int k = 0; k < 4000; k++) {
        hd_sim_joint_step(&j, 0.1, &t); /* 10 N m into the wall */
        least_env = fmin(least_env, t.env_torque_nm);
    }
    TEST_ASSERT_DOUBLE_WITHIN(1e-6, p.env_position_rad + 10.0 / p.env_stiffness_nm_rad,
                              t.output_angle_rad);
    for (int k = 0; k < 500; k++) {
        hd_sim_joint_step(&j, -0.1, &t); /* pulled away: the wall lets go */
        least_env = fmin(least_env, t.env_torque_nm);
    }
    TEST_ASSERT_TRUE(t.output_angle_rad < p.env_position_rad);
    TEST_ASSERT_EQUAL_FLOAT(0.0f, (float)least_env);
}

int main(int argc, char **argv)
{
    if (UnityParseOptions(argc, argv) != 0) {
        return 1;
    }
    UNITY_BEGIN();
    RUN_TEST(test_defaults_valid_and_checked);
    RUN_TEST(test_flexspline_mode_frequency);
    RUN_TEST(test_static_deflection_against_spring_and_gravity);
    RUN_TEST(test_energy_conserved_without_losses);
    RUN_TEST(test_gauge_artifact_moves_nothing_mesh_ripple_does);
    RUN_TEST(test_wall_pushes_never_pulls);
    return UNITY_END();
}
