/*
 * hdctrl-bench: the firmware's closed torque loop on the host against the
 * dynamic joint (hal/simdyn: sim/hd_sim_joint behind the sensors,
 * hal/simdrive as the drive), as tests/firmware/test_fw_closed_loop.c runs
 * it, for the control benchmark (tools/hdtools/bench/control*.py).
 *
 *   hdctrl-bench --input IN --out OUT.csv [options]
 *   hdctrl-bench --defaults     (the options below that a joint flashed with
 *                                the defaults runs, with their values)
 *
 * IN has one line per tick: "setpoint_nm inject_a speed_rad_s".  setpoint_nm
 * is the SETPOINT frame's torque (TORQUE: the torque; IMPEDANCE: tau_ff);
 * speed_rad_s is the dynamometer's speed (--load dyno); inject_a
 * is added to the current the firmware commands before the drive sees it:
 * the loop broken at the plant input for the margin measurement (the
 * firmware's own command is logged apart, so L = -cmd / drive per
 * frequency).  OUT gets one row per tick of commands and the simulation's
 * truth (the header names the columns).
 *
 * The load on the output (--load):
 *   dyno   a velocity servo (PI on the true output speed, like a
 *          dynamometer: --dyno-kv, --dyno-ki) holding the input's speed:
 *          the mean speed is exact, at 0 it holds the position
 *   free   nothing but --person-nm, a constant torque of a person
 *   wall   a stiff wall at --wall-rad (--wall-stiffness, --wall-damping),
 *          plus --person-nm
 * --preroll N: the first N ticks run ZERO_TORQUE with the dynamometer on
 * the input's speed whatever the load (the joint back-driven, so that the
 * filter has seen it move before the scene starts).
 * --sensor gauge|ideal: gauge (the default) is the simulated strain gauge,
 * the true output torque plus its sensing artifact (the 2x line that moves
 * nothing) and white noise; ideal is the same gauge with the artifact and
 * the noise switched off (gauge_ripple_nm 0, noise_nm 0): it reads the
 * simulation's true output torque (the real meshing ripple included) to
 * the ADC's resolution, a tick late as the gauge does.  A bench-only
 * diagnostic (the control benchmark's ideal-sensor bound), not a product
 * sensor: the firmware is the same, only the simulated sensor changes.
 * The simulated joint's physics (hd_sim_joint_params_t, the drive's and
 * the gauge's; each default is the 40 N m class joint's, hd_sim_joint_default,
 * hal_simdrive_default, hal_simdyn_sensor_default), each range-checked:
 *   --motor-inertia-kgm2 --motor-viscous-nm-s-rad --motor-coulomb-nm
 *   --motor-stribeck-nm --motor-stribeck-velocity-rad-s --stiffness-nm-rad
 *   --damping-nm-s-rad --output-inertia-kgm2 --output-viscous-nm-s-rad
 *   --mesh-ripple-nm --mesh-ripple-phase-rad --gauge-ripple-nm
 *   --gauge-ripple-phase-rad   (the joint, sim/hd_sim_joint.h)
 *   --kt-error --current-bandwidth-hz   (the drive, hal/simdrive)
 *   --noise-nm   (the gauge's white noise, N m rms)
 * The gear ratio, the tick and the encoders are not options: the firmware
 * is configured for them (its defaults), and a joint that differs there is
 * a different configuration, not a different joint of the class.
 * Every other parameter is the firmware's default: the firmware is told
 * nothing about the plant (a plant option changes the simulation only).
 * Exit 0 with OUT whole, or one line on stderr and 1 (2: usage).
 */
#include <errno.h>
#include <math.h>
#include <stdio.h>
#include <stdlib.h>
#include <string.h>

#include "hal_mock.h"
#include "hal_simdyn.h"
#include "hd_calib_record.h"
#include "hd_fw.h"
#include "hd_hostio.h"
#include "hd_params.h"

#define MAX_TICKS 400000u
#define MAX_SETS 8u /* --set KEY=VALUE options */
#define MAX_INPUT_BYTES (64u * 1024u * 1024u)

typedef struct {
    const char *input, *out;
    int mode;
    int feedback;
    double kp, ki, kd, ff, ilim, lowpass_hz, notch_width_hz, artifact_hz;
    double friction_rest_nm, friction_rate;
    int lowpass_order, notch_mask;
    int load;           /* 0 dyno, 1 free, 2 wall */
    double dyno_kv, dyno_ki, person_nm;
    double wall_rad, wall_k, wall_d;
    double imp_kp, imp_kd, imp_q_rad;
    unsigned seed;
    size_t preroll;
    int sensor;         /* 0 gauge, 1 ideal (bench-only: no artifact, no noise) */
    hd_sim_joint_params_t joint;   /* the simulated joint (the plant options) */
    hal_simdrive_config_t drive;
    double noise_nm;
    const hd_param_info_t *set_param[MAX_SETS]; /* --set: firmware parameters (checked */
    float set_value[MAX_SETS];                  /* when parsed), over the defaults */
    unsigned n_sets;
} opts_t;

#define TWO_PI_RAD 6.283185307179586

/* ctrl_feedback's values, by name */
static const char *const FEEDBACKS[] = {"filtered", "raw", "lowpass", "none", "narrow"};

static hal_mock_t mock; /* the CAN part only */
static hal_simdyn_t dyn;
static hal_t hal;
static hd_fw_t fw;

/* The break point: what the firmware commands, and the injected current. */
static hal_actuator_t drive_port;
static double inject_a, cmd_a;

static int cmd_current(void *ctx, float current_a)
{
    (void)ctx;
    cmd_a = (double)current_a;
    return drive_port.command_current(drive_port.ctx, (float)(cmd_a + inject_a));
}

static int fail(const char *msg, const char *what)
{
    fprintf(stderr, "hdctrl-bench: %s%s%s\n", msg, what ? ": " : "", what ? what : "");
    return 1;
}

/* The plant options: where each goes and the range it is checked against
 * (what the simulation models as a joint's physics, not the random space:
 * tools/hdmaint/bench/control_random.py draws within them). */
typedef struct {
    const char *name;
    double *dst;
    double lo, hi;
} plant_opt_t;

#define PLANT_OPTS 16

static void plant_table(opts_t *o, plant_opt_t t[PLANT_OPTS])
{
    hd_sim_joint_params_t *j = &o->joint;
    const plant_opt_t all[PLANT_OPTS] = {
        {"--motor-inertia-kgm2", &j->motor_inertia_kgm2, 1e-7, 1e-2},
        {"--motor-viscous-nm-s-rad", &j->motor_viscous_nm_s_rad, 0.0, 0.1},
        {"--motor-coulomb-nm", &j->motor_coulomb_nm, 0.0, 1.0},
        {"--motor-stribeck-nm", &j->motor_stribeck_nm, 0.0, 1.0},
        {"--motor-stribeck-velocity-rad-s", &j->motor_stribeck_velocity_rad_s, 1e-3, 1e3},
        {"--stiffness-nm-rad", &j->stiffness_nm_rad, 1e2, 1e7},
        {"--damping-nm-s-rad", &j->damping_nm_s_rad, 0.0, 1e4},
        {"--output-inertia-kgm2", &j->output_inertia_kgm2, 1e-4, 1e3},
        {"--output-viscous-nm-s-rad", &j->output_viscous_nm_s_rad, 0.0, 1e3},
        {"--mesh-ripple-nm", &j->mesh_ripple_nm, 0.0, 50.0},
        {"--mesh-ripple-phase-rad", &j->mesh_ripple_phase_rad, -TWO_PI_RAD, TWO_PI_RAD},
        {"--gauge-ripple-nm", &j->gauge_ripple_nm, 0.0, 50.0},
        {"--gauge-ripple-phase-rad", &j->gauge_ripple_phase_rad, -TWO_PI_RAD, TWO_PI_RAD},
        {"--kt-error", &o->drive.kt_error, -0.5, 0.5},
        {"--current-bandwidth-hz", &o->drive.bandwidth_hz, 10.0, 1e5},
        {"--noise-nm", &o->noise_nm, 0.0, 10.0},
    };
    memcpy(t, all, sizeof all);
}

/* k v as a plant option of o: 1 (set), 0 (not a plant option) or -1 (its
 * one-line message printed). */
static int plant_option(opts_t *o, const char *k, const char *v, bool num, double x)
{
    plant_opt_t t[PLANT_OPTS];
    plant_table(o, t);
    for (size_t i = 0; i < PLANT_OPTS; i++) {
        if (strcmp(k, t[i].name) != 0) {
            continue;
        }
        if (!num) {
            fprintf(stderr, "hdctrl-bench: %s: not a number: %s\n", k, v);
            return -1;
        }
        if (!(x >= t[i].lo && x <= t[i].hi)) {
            fprintf(stderr, "hdctrl-bench: %s: %s is outside [%g, %g]\n", k, v, t[i].lo,
                    t[i].hi);
            return -1;
        }
        *t[i].dst = x;
        return 1;
    }
    return 0;
}

/* "name value" with the fewest digits that read back to the same value
 * (float: the law's parameters; else double). */
static void print_value(const char *name, double v, bool is_float)
{
    char buf[40];
    for (int digits = 1; digits <= 17; digits++) {
        snprintf(buf, sizeof buf, "%.*g", digits, v);
        const double back = strtod(buf, NULL);
        if (is_float ? (float)back == (float)v : back == v) {
            break;
        }
    }
    printf("%s %s\n", name, buf);
}

static int pick(const char *v, const char *const *names, int n)
{
    for (int i = 0; i < n; i++) {
        if (strcmp(v, names[i]) == 0) {
            return i;
        }
    }
    return -1;
}

static int number(const char *v, double *out)
{
    char *end;
    errno = 0;
    *out = strtod(v, &end);
    return (errno != 0 || end == v || *end != '\0' || !isfinite(*out)) ? -1 : 0;
}

/* The runner's defaults: the firmware's (hd_ctrl_config_default) and the
 * simulated joint's, drive's and gauge's. */
static void defaults(opts_t *o)
{
    hd_ctrl_config_t def;
    hd_ctrl_config_default(&def);
    const hd_ctrl_config_t *d = &def;
    *o = (opts_t){.mode = HD_CTRL_TORQUE, .feedback = d->feedback, .kp = d->torque_kp,
                  .ki = d->torque_ki_per_s, .ff = d->torque_ff,
                  .ilim = d->integral_limit_nm, .kd = d->torque_kd_s, .lowpass_hz = d->lowpass_hz,
                  .notch_width_hz = d->notch_width_hz, .artifact_hz = d->artifact_hz, .lowpass_order = d->lowpass_order,
                  .notch_mask = d->notch_mask, .friction_rest_nm = d->friction_rest_nm,
                  .friction_rate = d->friction_rate_nm_s, .dyno_kv = 50.0, .dyno_ki = 5000.0,
                  .wall_k = 2e4, .wall_d = 5.0, .imp_kd = 0.0, .seed = 0x5EEDu};
    hd_sim_joint_default(&o->joint);
    hal_simdrive_default(&o->drive);
    hal_simdyn_sensor_t sens;
    hal_simdyn_sensor_default(&sens);
    o->noise_nm = sens.noise_nm;
}

/* --defaults: the firmware's torque loop and the plant as options with
 * their default values, one "option value" a line (what a joint flashed
 * with the defaults runs; tools/hdmaint/bench/control_random.py). */
static void print_defaults(void)
{
    opts_t o;
    defaults(&o);
    printf("--feedback %s\n", FEEDBACKS[o.feedback]);
    const struct { const char *name; double v; } law[] = {
        {"--kp", o.kp}, {"--ki", o.ki}, {"--kd", o.kd}, {"--ff", o.ff}, {"--ilim", o.ilim},
        {"--lowpass-hz", o.lowpass_hz}, {"--notch-width-hz", o.notch_width_hz},
        {"--artifact-hz", o.artifact_hz}, {"--friction-rest-nm", o.friction_rest_nm},
        {"--friction-rate", o.friction_rate}};
    for (size_t i = 0; i < sizeof law / sizeof law[0]; i++) {
        print_value(law[i].name, law[i].v, true);
    }
    printf("--lowpass-order %d\n--notch-mask %d\n", o.lowpass_order, o.notch_mask);
    plant_opt_t t[PLANT_OPTS];
    plant_table(&o, t);
    for (size_t i = 0; i < PLANT_OPTS; i++) {
        print_value(t[i].name, *t[i].dst, false);
    }
}

static int parse(int argc, char **argv, opts_t *o)
{
    static const char *const modes[] = {"stop", "damp", "torque", "impedance", "zero_torque"};
    static const char *const loads[] = {"dyno", "free", "wall"};
    static const char *const sensors[] = {"gauge", "ideal"};
    defaults(o);
    for (int i = 1; i < argc; i++) {
        const char *k = argv[i];
        if (i + 1 >= argc) {
            fprintf(stderr, "hdctrl-bench: %s needs a value\n", k);
            return -1;
        }
        const char *v = argv[++i];
        double x = 0.0;
        const bool num = number(v, &x) == 0;
        struct { const char *name; double *dst; } nums[] = {
            {"--kp", &o->kp}, {"--ki", &o->ki}, {"--kd", &o->kd}, {"--ff", &o->ff}, {"--ilim", &o->ilim},
            {"--lowpass-hz", &o->lowpass_hz}, {"--notch-width-hz", &o->notch_width_hz},
            {"--artifact-hz", &o->artifact_hz},
            {"--friction-rest-nm", &o->friction_rest_nm}, {"--friction-rate", &o->friction_rate},
            {"--dyno-kv", &o->dyno_kv}, {"--dyno-ki", &o->dyno_ki},
            {"--person-nm", &o->person_nm}, {"--wall-rad", &o->wall_rad},
            {"--wall-stiffness", &o->wall_k}, {"--wall-damping", &o->wall_d},
            {"--imp-kp", &o->imp_kp}, {"--imp-kd", &o->imp_kd}, {"--imp-q", &o->imp_q_rad}};
        bool done = false;
        for (size_t j = 0; j < sizeof nums / sizeof nums[0]; j++) {
            if (strcmp(k, nums[j].name) == 0) {
                if (!num) {
                    fprintf(stderr, "hdctrl-bench: %s: not a number: %s\n", k, v);
                    return -1;
                }
                *nums[j].dst = x;
                done = true;
            }
        }
        const int plant = plant_option(o, k, v, num, x);
        if (plant < 0) {
            return -1;
        }
        done = done || plant > 0;
        if (done) {
            continue;
        }
        if (strcmp(k, "--set") == 0) {
            const char *eq = strchr(v, '=');
            double sv = 0.0;
            if (o->n_sets >= MAX_SETS || eq == NULL || number(eq + 1, &sv) != 0) {
                fprintf(stderr, "hdctrl-bench: --set KEY=VALUE (a number, at most %u): %s\n",
                        MAX_SETS, v);
                return -1;
            }
            const hd_param_info_t *param = hd_param_by_key(v, (size_t)(eq - v));
            const hd_fw_err_t bad = hd_param_check(param, (float)sv);
            if (bad != HD_FW_OK) {
                fprintf(stderr, "hdctrl-bench: --set %s: %s\n", v, hd_fw_err_str(bad));
                return -1;
            }
            o->set_param[o->n_sets] = param;
            o->set_value[o->n_sets++] = (float)sv;
        } else if (strcmp(k, "--input") == 0) {
            o->input = v;
        } else if (strcmp(k, "--out") == 0) {
            o->out = v;
        } else if (strcmp(k, "--mode") == 0 && (o->mode = pick(v, modes, 5)) >= 0) {
        } else if (strcmp(k, "--feedback") == 0 && (o->feedback = pick(v, FEEDBACKS, 5)) >= 0) {
        } else if (strcmp(k, "--load") == 0 && (o->load = pick(v, loads, 3)) >= 0) {
        } else if (strcmp(k, "--sensor") == 0 && (o->sensor = pick(v, sensors, 2)) >= 0) {
        } else if (strcmp(k, "--lowpass-order") == 0 && num) {
            o->lowpass_order = (int)x;
        } else if (strcmp(k, "--notch-mask") == 0 && num && x >= 0 && x <= 255) {
            o->notch_mask = (int)x;
        } else if (strcmp(k, "--preroll") == 0 && num && x >= 0 && x <= MAX_TICKS) {
            o->preroll = (size_t)x;
        } else if (strcmp(k, "--seed") == 0 && num && x >= 0 && x < 4294967296.0) {
            o->seed = (unsigned)x;
        } else {
            fprintf(stderr, "hdctrl-bench: bad option or value: %s %s\n", k, v);
            return -1;
        }
    }
    if (o->input == NULL || o->out == NULL) {
        fprintf(stderr, "usage: hdctrl-bench --input IN --out OUT.csv [--mode M] [--feedback F] "
                        "[--kp --ki --ff --lowpass-hz --lowpass-order --notch-mask "
                        "--notch-width-hz --artifact-hz --friction-rest-nm --friction-rate] [--load dyno|free|wall --dyno-kv --dyno-ki --person-nm "
                        "--wall-rad --wall-stiffness --wall-damping] [--imp-kp --imp-kd "
                        "--imp-q] [--preroll N] [--seed] [--set KEY=VALUE ...] [--sensor gauge|ideal] [plant options: "
                        "--motor-inertia-kgm2 --motor-viscous-nm-s-rad --motor-coulomb-nm "
                        "--motor-stribeck-nm --motor-stribeck-velocity-rad-s --stiffness-nm-rad "
                        "--damping-nm-s-rad --output-inertia-kgm2 --output-viscous-nm-s-rad "
                        "--mesh-ripple-nm --mesh-ripple-phase-rad --gauge-ripple-nm "
                        "--gauge-ripple-phase-rad --kt-error --current-bandwidth-hz --noise-nm]\n");
        return -1;
    }
    return 0;
}

#define COLS 3u

/* The input's columns; *n ticks.  Returns NULL (+ message) on error. */
static double *read_input(const char *path, size_t *n)
{
    char err[160];
    size_t len = 0;
    char *text = hd_hostio_read_file(path, MAX_INPUT_BYTES, &len, err, sizeof err);
    if (text == NULL) {
        fprintf(stderr, "hdctrl-bench: %s\n", err);
        return NULL;
    }
    double *v = malloc(COLS * MAX_TICKS * sizeof *v);
    size_t k = 0;
    char *p = text;
    while (v != NULL && *p != '\0') {
        for (unsigned c = 0; c < COLS; c++) {
            char *end;
            const double a = strtod(p, &end);
            if (end == p || k >= MAX_TICKS || !isfinite(a)) {
                fprintf(stderr, "hdctrl-bench: %s: line %zu: want %u finite numbers (at most "
                                "%u lines)\n", path, k + 1u, COLS, MAX_TICKS);
                free(text);
                free(v);
                return NULL;
            }
            p = end;
            v[COLS * k + c] = a;
        }
        k++;
        while (*p == ' ' || *p == '\t' || *p == '\r' || *p == '\n') {
            p++;
        }
    }
    const bool bad = v == NULL || *p != '\0' || k == 0u;
    free(text);
    if (bad) {
        fprintf(stderr, "hdctrl-bench: %s: not lines of \"setpoint_nm inject_a speed_rad_s\"\n",
                path);
        free(v);
        return NULL;
    }
    *n = k;
    return v;
}

static int setup(const opts_t *o, hd_fw_config_t *cfg)
{
    hd_sim_joint_params_t jp = o->joint;
    jp.payload_kg = 0.0;
    jp.link_gravity_nm = 0.0;
    if (o->load == 2) {
        jp.env = HD_SIM_ENV_WALL;
        jp.env_position_rad = o->wall_rad;
        jp.env_stiffness_nm_rad = o->wall_k;
        jp.env_damping_nm_s_rad = o->wall_d;
    }
    const hal_simdrive_config_t dc = o->drive;
    hal_simdyn_sensor_t sc;
    hal_simdyn_sensor_default(&sc);
    sc.noise_nm = o->noise_nm;
    sc.offset_v = 0.0; /* the firmware's default calibration: no record stored */
    sc.gain_nm_per_v = HD_CALIB_NOMINAL_GAIN_NM_PER_V;
    sc.seed = o->seed;
    if (o->sensor == 1) { /* the ideal-sensor bound: the gauge without what is not torque */
        jp.gauge_ripple_nm = 0.0;
        sc.noise_nm = 0.0;
    }
    char err[120];
    if (hal_simdyn_init(&dyn, &jp, &dc, &sc, err, sizeof err) != 0) {
        return fail("simulated joint", err);
    }
    hal = (hal_t){0};
    hal_mock_init(&mock);
    hal_mock_bind_can(&mock, &hal.can);
    mock.tx_store = false;
    hal_simdyn_bind(&dyn, &hal);
    drive_port = hal.actuator;
    hal.actuator.command_current = cmd_current;
    hd_fw_config_default(cfg);
    hd_ctrl_config_t *k = &cfg->ctrl;
    k->feedback = (uint8_t)o->feedback;
    k->torque_kp = (float)o->kp;
    k->torque_ki_per_s = (float)o->ki;
    k->torque_ff = (float)o->ff;
    k->integral_limit_nm = (float)o->ilim;
    k->torque_kd_s = (float)o->kd;
    k->lowpass_hz = (float)o->lowpass_hz;
    k->lowpass_order = (uint8_t)o->lowpass_order;
    k->notch_mask = (uint8_t)o->notch_mask;
    k->notch_width_hz = (float)o->notch_width_hz;
    k->artifact_hz = (float)o->artifact_hz;
    k->friction_rest_nm = (float)o->friction_rest_nm;
    k->friction_rate_nm_s = (float)o->friction_rate;
    for (unsigned i = 0; i < o->n_sets; i++) {
        const hd_fw_err_t bad = hd_param_set(o->set_param[i], cfg, o->set_value[i]);
        if (bad != HD_FW_OK) { /* range checked by parse: a read-only row */
            return fail(o->set_param[i]->key, hd_fw_err_str(bad));
        }
    }
    const int rc = hd_fw_init(&fw, &hal, cfg);
    if (rc != HD_FW_OK) {
        return fail("firmware configuration rejected", hd_fw_err_str(rc));
    }
    const hd_can_gains_t g = {(float)o->imp_kp, (float)o->imp_kd};
    hal_can_frame_t f;
    hd_can_encode_gains(cfg->node_id, &g, &f);
    return hal_mock_push_rx(&mock, &f) == 0 ? 0 : fail("CAN receive queue full", NULL);
}

static int run(const opts_t *o, const double *in, size_t n, hd_out_t *out)
{
    hd_fw_config_t cfg;
    if (setup(o, &cfg) != 0) {
        return 1;
    }
    hd_out_printf(out, "tick,setpoint_nm,inject_a,cmd_a,true_torque_nm,gauge_nm,raw_nm,"
                       "filtered_nm,fb_nm,torque_ref_nm,motor_angle_rad,output_angle_rad,"
                       "output_velocity_rad_s,person_nm,env_nm,mode\n");
    double dyno_int = 0.0;
    for (size_t k = 0; k < n; k++) {
        const bool pre = k < o->preroll;
        const hd_can_setpoint_t sp = {.mode = pre ? (uint8_t)HD_CTRL_ZERO_TORQUE : (uint8_t)o->mode,
                                      .seq = (uint8_t)k,
                                      .torque_nm = (float)in[COLS * k],
                                      .position_rad = (float)o->imp_q_rad,
                                      .velocity_rad_s = 0.0f};
        hal_can_frame_t f;
        hd_can_encode_setpoint(cfg.node_id, &sp, &f);
        if (hal_mock_push_rx(&mock, &f) != 0) {
            return fail("CAN receive queue full", NULL);
        }
        inject_a = in[COLS * k + 1u];
        cmd_a = 0.0;
        hd_fw_isr(&fw);
        hd_fw_background(&fw);
        const double v = dyn.joint.x.output_velocity_rad_s;
        double person = o->person_nm;
        if (o->load == 0 || pre) {
            const double target = in[COLS * k + 2u];
            dyno_int += o->dyno_ki * (target - v) * dyn.joint.p.ts_s;
            person = o->dyno_kv * (target - v) + dyno_int;
        }
        dyn.joint.person_torque_nm = person;
        const hd_fw_sample_t *s = &fw.last;
        const hd_ctrl_output_t *c = &fw.control.out;
        hal_simdyn_tick(&dyn);
        const hd_sim_joint_truth_t *t = &dyn.truth;
        hd_out_printf(out, "%zu,%.5g,%.6g,%.6g,%.7g,%.7g,%.7g,%.7g,%.7g,%.7g,%.9g,%.9g,%.7g,%.7g,"
                           "%.7g,%d\n",
                      k, in[COLS * k], inject_a, cmd_a, t->output_torque_nm, t->gauge_torque_nm,
                      (double)s->torque_raw_nm, (double)s->torque_filtered_nm,
                      (double)c->torque_fb_nm, (double)c->torque_ref_nm, t->motor_angle_rad,
                      t->output_angle_rad, t->output_velocity_rad_s, t->person_torque_nm,
                      t->env_torque_nm, (int)c->mode);
    }
    return 0;
}

int main(int argc, char **argv)
{
    if (argc == 2 && strcmp(argv[1], "--defaults") == 0) {
        print_defaults();
        return fflush(stdout) == 0 && !ferror(stdout) ? 0 : 1;
    }
    opts_t o;
    if (parse(argc, argv, &o) != 0) {
        return 2;
    }
    size_t n = 0;
    double *in = read_input(o.input, &n);
    if (in == NULL) {
        return 1;
    }
    hd_out_t out;
    char err[200];
    if (hd_out_open(&out, o.out, false, err, sizeof err) != 0) {
        free(in);
        return fail(err, NULL);
    }
    const int rc = run(&o, in, n, &out);
    free(in);
    if (rc != 0) {
        hd_out_abort(&out);
        return rc;
    }
    if (hd_out_commit(&out, err, sizeof err) != 0) {
        return fail(err, NULL);
    }
    return 0;
}
