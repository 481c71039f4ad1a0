/*
 * The firmware closing its torque loop on the host against the dynamic
 * joint (hal/simdyn: sim/hd_sim_joint behind the sensors, hal/simdrive as
 * the drive), judged by the simulation's truth, never by what the firmware
 * measures:
 *   - a constant TORQUE setpoint against a viscous load: the true output
 *     torque's mean is the setpoint (the loop's integral on the filtered
 *     torque, whose slow part is the real load);
 *   - the ripple in the true output torque at 2x the motor angle, with the
 *     filtered torque fed back against the raw one (the same gains: the
 *     law's defaults, not tuned to equal margins): raw feedback chases the
 *     gauge's sensing artifact and turns it into real torque.
 * The 2x component is fitted by least squares on sin/cos(2 theta_m) of the
 * true motor angle over the last second.
 */
#include <math.h>
#include <stdio.h>
#include <string.h>

#include "hal_mock.h"
#include "hal_simdyn.h"
#include "hd_calib_record.h"
#include "hd_fw.h"
#include "unity.h"

void setUp(void) {}
void tearDown(void) {}

static hal_mock_t mock;  /* the CAN part only */
static hal_simdyn_t dyn;
static hal_t hal;
static hd_fw_t fw;

#define RUN_TICKS 4000
#define FIT_FROM 3000

typedef struct {
    double mean_nm;       /* true output torque, last second */
    double line2_nm;      /* amplitude of its 2x motor-angle component */
    double rms_nm;        /* rms about the mean */
    double speed_rad_s;   /* mean output speed */
} loop_result_t;

static void viscous_load(hd_sim_joint_params_t *p)
{
    hd_sim_joint_default(p);
    p->payload_kg = 0.0;
    p->link_gravity_nm = 0.0;
    p->env = HD_SIM_ENV_SPRING; /* K_e = 0: a damper, the output runs at T / D_e */
    p->env_stiffness_nm_rad = 0.0;
    p->env_damping_nm_s_rad = 4.0;
}

static loop_result_t run_loop(uint8_t feedback, float torque_nm)
{
    hd_sim_joint_params_t jp;
    viscous_load(&jp);
    hal_simdrive_config_t dc;
    hal_simdrive_default(&dc);
    hal_simdyn_sensor_t sc;
    hal_simdyn_sensor_default(&sc);
    sc.offset_v = 0.0; /* the firmware's default calibration: 6.60 N m/V, 0 V */
    sc.gain_nm_per_v = HD_CALIB_NOMINAL_GAIN_NM_PER_V;
    char err[80];
    TEST_ASSERT_EQUAL_INT(0, hal_simdyn_init(&dyn, &jp, &dc, &sc, err, sizeof err));
    hal = (hal_t){0};
    hal_mock_init(&mock);
    hal_mock_bind_can(&mock, &hal.can);
    mock.tx_store = false;
    hal_simdyn_bind(&dyn, &hal);
    hd_fw_config_t cfg;
    hd_fw_config_default(&cfg);
    cfg.ctrl.feedback = feedback;
    TEST_ASSERT_EQUAL_INT(HD_FW_OK, hd_fw_init(&fw, &hal, &cfg));

    double s = 0, c = 0, ss = 0, cc = 0, sc2 = 0, ys = 0, yc = 0, y = 0, y2 = 0, w = 0;
    int n = 0;
    for (int k = 0; k < RUN_TICKS; k++) {
        const hd_can_setpoint_t sp = {HD_CTRL_TORQUE, (uint8_t)k, torque_nm, 0.0f, 0.0f};
        hal_can_frame_t f;
        hd_can_encode_setpoint(cfg.node_id, &sp, &f);
        TEST_ASSERT_EQUAL_INT(0, hal_mock_push_rx(&mock, &f));
        hd_fw_isr(&fw);
        hd_fw_background(&fw);
        hal_simdyn_tick(&dyn);
        if (k >= FIT_FROM) {
            const hd_sim_joint_truth_t *t = &dyn.truth;
            const double a = 2.0 * t->motor_angle_rad;
            const double si = sin(a), co = cos(a), v = t->output_torque_nm;
            s += si, c += co, ss += si * si, cc += co * co, sc2 += si * co;
            ys += v * si, yc += v * co, y += v, y2 += v * v, w += t->output_velocity_rad_s;
            n++;
        }
    }
    TEST_ASSERT_EQUAL_INT(HD_CTRL_TORQUE, fw.control.out.mode);
    /* least squares v = m + a sin + b cos (3x3 normal equations, Cramer) */
    const double m3[3][3] = {{n, s, c}, {s, ss, sc2}, {c, sc2, cc}};
    const double r[3] = {y, ys, yc};
    double det = 0, sol[3];
    for (int col = -1; col < 3; col++) {
        double m[3][3];
        memcpy(m, m3, sizeof m);
        if (col >= 0) {
            for (int i = 0; i < 3; i++) {
                m[i][col] = r[i];
            }
        }
        const double d = m[0][0] * (m[1][1] * m[2][2] - m[1][2] * m[2][1]) -
                         m[0][1] * (m[1][0] * m[2][2] - m[1][2] * m[2][0]) +
                         m[0][2] * (m[1][0] * m[2][1] - m[1][1] * m[2][0]);
        if (col < 0) {
            det = d;
        } else {
            sol[col] = d / det;
        }
    }
    loop_result_t out;
    out.mean_nm = y / n;
    out.line2_nm = hypot(sol[1], sol[2]);
    out.rms_nm = sqrt(fmax(0.0, y2 / n - out.mean_nm * out.mean_nm));
    out.speed_rad_s = w / n;
    return out;
}

static void test_torque_tracking_and_ripple_filtered_vs_raw(void)
{
    const float tau = 10.0f;
    const loop_result_t filt = run_loop(HD_CTRL_FB_FILTERED, tau);
    const loop_result_t raw = run_loop(HD_CTRL_FB_RAW, tau);
    const loop_result_t open = run_loop(HD_CTRL_FB_NONE, tau);
    const char *names[3] = {"filtered", "raw", "open loop"};
    const loop_result_t *all[3] = {&filt, &raw, &open};
    for (int i = 0; i < 3; i++) {
        printf("closed_loop: %-9s feedback, setpoint %.1f N m: true torque mean %.3f N m, "
               "2x line %.4f N m, rms %.4f N m, speed %.3f rad/s\n",
               names[i], (double)tau, all[i]->mean_nm, all[i]->line2_nm, all[i]->rms_nm,
               all[i]->speed_rad_s);
    }
    printf("closed_loop: true-torque 2x ripple filtered / raw = %.3f (goal <= 0.5)\n",
           filt.line2_nm / raw.line2_nm);
    TEST_ASSERT_DOUBLE_WITHIN(0.03 * (double)tau, (double)tau, filt.mean_nm);
    TEST_ASSERT_TRUE(filt.line2_nm < 0.5 * raw.line2_nm);
}

int main(void)
{
    UNITY_BEGIN();
    RUN_TEST(test_torque_tracking_and_ripple_filtered_vs_raw);
    return UNITY_END();
}
