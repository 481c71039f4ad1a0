/*
 * hd_bench: instruction-count benchmark image (no SysTick: nothing
 * interrupts a measured interval).  Run it in QEMU with the counting plugin
 * (tools/qemu-plugin/hdcount.c); `tools/target budget` does both and prints
 * the table.
 *
 * For each model size it measures, call by call, between the markers
 * hd_mark_begin / hd_mark_end (board.h):
 *   kf:NAME     hd_kf_step alone (the filter update)
 *   isr:NAME    hd_fw_isr, the whole 1 kHz tick: sensors (hal_mock), encoder
 *               deltas, tracker, expected torque, filter, faults, telemetry
 *               (2 frames per tick at 1 kHz) and the heartbeat on tick 0
 *   isrcmd:NAME hd_fw_isr with commands arriving every tick (HD_FW_RX_PER_TICK
 *               frames: a BLOCK_ENABLE toggle of block 0, which the tick
 *               applies to the running filter with hd_kf_set_block_enabled,
 *               O(n), then SET_PARAM r_nm2, which rebuilds the model),
 *               hd_fw_background run between ticks (outside the markers):
 *               each tick takes frames, applies the change the background
 *               prepared and sends up to HD_FW_ACKS_PER_TICK ACKs; the model
 *               builds are not counted because they are not in the tick
 *   isrctrl:NAME hd_fw_isr on a board with a drive (a recording actuator):
 *               the control stage runs every tick, with HD_FW_RX_PER_TICK
 *               control frames arriving every tick (a TORQUE SETPOINT and a
 *               GAINS frame, both decoded and checked by the tick itself)
 *   isrctrlcmd:NAME  the same board running TORQUE (one SETPOINT at tick 0)
 *               with the isrcmd command frames on every other tick
 *   isrident:NAME  isrctrl with an identification run on (IDENT_START with
 *               the first SETPOINT instead of GAINS; the waveform is built
 *               by the background, outside the count): the excitation
 *               added to the drive command and an IDENT frame every tick
 *   ctrl:default hd_ctrl_step alone, cycling TORQUE, IMPEDANCE, ZERO_TORQUE
 *               and DAMP over inputs that reach the velocity, position and
 *               current limits
 *   dense:NAME  the dense textbook float32 filter, same model and inputs
 *               (tests/bench/dense_kf_f32.c, the compute benchmark's peer)
 *   kffrozen:NAME, kflost:NAME, kfclamp:NAME, kfreset:NAME, kfworst:NAME,
 *               hd_kf_step on its slow paths, every call: motor blocks over
 *               Nyquist (held, Joseph weights); a phase advance beyond
 *               HD_KF_PHASE_LOST_RAD (the blocks restart); every covariance
 *               diagonal above p_max (p_max below q: the clamp on every
 *               state); a non-finite state written into the filter before
 *               the call (the reset); and all at once with a +-1000 N m
 *               innovation (phase lost, output block frozen, offset jump,
 *               clamp)
 *   kfrollback:NAME  hd_kf_step ending a transient's event on every call
 *               (written into the filter before it: the blocks go back to
 *               their states at its start)
 *   kfpartial:NAME hd_kf_step with every gain fraction below 1 and no block
 *               frozen (Joseph weights on every tile): motor blocks below
 *               q_motion_ref_rad, output_learn_scale 0.5
 * and "empty" (begin immediately followed by end) for the marker overhead,
 * and "loop" (hd_bench_loop(10), then hd_bench_loop(1010): the counts must
 * differ by exactly 2 x 1000, a closed-form check of the counter).
 * Before each section it prints "section LABEL STATES" on the console; the
 * plugin closes the section at hd_mark_section.
 *
 * Models: 4 states (motor orders 2, 4), 6 (+ output order 1), 8 (+ motor
 * order 6), default (the firmware's default: 3 blocks + offset = 7) and max
 * (HD_KF_MAX_BLOCKS = 8 blocks + offset = 17).
 */
#include <stdbool.h>
#include <stdint.h>
#include <string.h>

#include "board.h"
#include "board_io.h"
#include "dense_kf_f32.h"
#include "hal_mock.h"
#include "hd_can_proto.h"
#include "hd_fw.h"
#include "hd_kf.h"
#include "hd_lockstep.h"
#include "hd_trig.h"
#include "semihost.h"

#define CALLS 64u
#define MOTOR_SPEED_RAD_S 156.0f /* the paper's test speed */

typedef struct {
    const char *name;
    uint8_t motor_blocks;   /* motor orders 2, 4, 6, ... */
    uint8_t output_blocks;  /* output orders 1, 2, ... */
    uint8_t extra_motor;    /* motor orders 1, 3, 5, ... (the max model) */
    uint8_t offset;
    bool fw_default;        /* use hd_fw_config_default's model as is */
} model_t;

static const model_t MODELS[] = {
    {"4", 2, 0, 0, 0, false},
    {"6", 2, 1, 0, 0, false},
    {"8", 3, 1, 0, 0, false},
    {"default", 0, 0, 0, 0, true},
    {"max", 4, 2, 2, 1, false},
};

static hd_fw_t g_fw;
static hd_ls_drive_t g_drive;
static hal_mock_t g_mock;
static hal_t g_hal;
static hd_kf_t g_kf;
static dense_kf_f32_t g_dense;

static void section(const char *label, const char *model, uint32_t states)
{
    sh_puts("section ");
    sh_puts(label);
    sh_puts(":");
    sh_puts(model);
    board_print_u32(" ", states);
}

static void calibration_section(const char *label)
{
    sh_puts("section ");
    sh_puts(label);
    board_print_u32(" ", 0u);
}

/* The model's filter configuration, on top of the firmware's defaults (noise,
 * settle times, Nyquist limit), so kf, isr and dense run the same size. */
static void model_config(const model_t *m, hd_fw_config_t *cfg)
{
    hd_fw_config_default(cfg);
    if (m->fw_default) {
        return;
    }
    float q_motor = cfg->kf.blocks[0].q_nm2;
    float q_output = q_motor;
    for (unsigned b = 0; b < cfg->kf.block_count; b++) {
        if (cfg->kf.blocks[b].lock == HD_KF_LOCK_OUTPUT) {
            q_output = cfg->kf.blocks[b].q_nm2;
        }
    }
    cfg->kf.block_count = 0;
    cfg->kf.offset_enabled = m->offset;
    for (unsigned i = 0; i < m->motor_blocks; i++) {
        (void)hd_kf_config_add_block(&cfg->kf, HD_KF_LOCK_MOTOR, 2.0f * (float)(i + 1u), q_motor);
    }
    for (unsigned i = 0; i < m->output_blocks; i++) {
        (void)hd_kf_config_add_block(&cfg->kf, HD_KF_LOCK_OUTPUT, (float)(i + 1u), q_output);
    }
    for (unsigned i = 0; i < m->extra_motor; i++) {
        (void)hd_kf_config_add_block(&cfg->kf, HD_KF_LOCK_MOTOR, 2.0f * (float)i + 1.0f, q_motor);
    }
}

/* Ripple at motor orders 2 and 4 on a slow torque, at 156 rad/s. */
static float test_torque_nm(uint32_t k, float motor_angle_rad)
{
    float s2, c2, s4, c4;
    hd_sincosf(2.0f * motor_angle_rad, &s2, &c2);
    hd_sincosf(4.0f * motor_angle_rad, &s4, &c4);
    (void)c2;
    (void)c4;
    return 5.0f + 0.001f * (float)(k % 100u) + 1.0f * s2 + 0.5f * s4;
}

static void wrap_angle(float *a)
{
    if (*a > HD_PI_F) {
        *a -= HD_TWO_PI_F;
    }
}

/* Sample k of the bench input: the same for every filter implementation. */
static hd_kf_input_t bench_input(uint32_t k, const hd_fw_config_t *cfg)
{
    const float d_motor = MOTOR_SPEED_RAD_S * HD_FW_TS_S;
    static float angle;
    if (k == 0u) {
        angle = 0.0f;
    }
    hd_kf_input_t in;
    memset(&in, 0, sizeof in);
    in.torque_meas_nm = test_torque_nm(k, angle);
    in.torque_expected_nm = 5.0f;
    in.d_motor_angle_rad = d_motor;
    in.d_output_angle_rad = d_motor / cfg->gear_ratio;
    angle += d_motor;
    wrap_angle(&angle);
    return in;
}

static void bench_kf(const hd_fw_config_t *cfg)
{
    if (hd_kf_init(&g_kf, &cfg->kf) != HD_KF_OK) {
        sh_exit(BOARD_EXIT_INIT);
    }
    for (uint32_t k = 0; k < CALLS; k++) {
        const hd_kf_input_t in = bench_input(k, cfg);
        hd_kf_output_t out;
        hd_mark_begin();
        hd_kf_step(&g_kf, &in, &out);
        hd_mark_end();
    }
}

static void bench_dense(const hd_fw_config_t *cfg)
{
    dense_kf_f32_init(&g_dense, &cfg->kf);
    for (uint32_t k = 0; k < CALLS; k++) {
        const hd_kf_input_t in = bench_input(k, cfg);
        dense_kf_f32_output_t out;
        hd_mark_begin();
        dense_kf_f32_step(&g_dense, &in, &out);
        hd_mark_end();
    }
}

typedef enum {
    PATH_FROZEN,
    PATH_LOST,
    PATH_CLAMP,
    PATH_RESET,
    PATH_WORST,
    PATH_PARTIAL,
    PATH_ROLLBACK
} kf_path_t;

/* hd_kf_step forced onto one of its slow paths on every call (see above). */
static void bench_kf_path(const hd_fw_config_t *cfg_in, kf_path_t path)
{
    hd_kf_config_t kcfg = cfg_in->kf;
    if (path == PATH_CLAMP || path == PATH_WORST) {
        kcfg.p0_nm2 = kcfg.output_p0_nm2 = kcfg.p_max_nm2 = 1.0e-9f;
    }
    if (path == PATH_PARTIAL) {
        kcfg.output_learn_scale = 0.5f; /* the operating mode's kind of value */
    }
    if (path == PATH_ROLLBACK) {
        kcfg.offset_jump_nm = 1.0e5f; /* every step quiet: the written event ends */
    }
    if (hd_kf_init(&g_kf, &kcfg) != HD_KF_OK) {
        sh_exit(BOARD_EXIT_INIT);
    }
    for (uint32_t k = 0; k < CALLS; k++) {
        hd_kf_input_t in = bench_input(k, cfg_in);
        if (path == PATH_PARTIAL) {
            in.d_motor_angle_rad = 0.01f; /* every motor block below q_motion_ref */
        } else if (path == PATH_FROZEN) {
            in.d_motor_angle_rad = 1.6f;  /* order 2: 3.2 rad > 0.9 pi */
        } else if (path == PATH_LOST || path == PATH_WORST) {
            in.d_motor_angle_rad = 13.0f; /* order 2: 26 rad, beyond four turns */
        }
        if (path == PATH_WORST) {
            in.d_output_angle_rad = 3.0f; /* output order 1 over Nyquist */
            in.torque_meas_nm = (k & 1u) ? 1000.0f : -1000.0f;
        }
        if (path == PATH_RESET) {
            g_kf.x[0] = (float)__builtin_nanf(""); /* a corrupted state */
        }
        if (path == PATH_ROLLBACK) {
            /* the last quiet step of a transient's event: the blocks go back */
            g_kf.jump_hold_steps = 1u;
            g_kf.event_peak_nm2 = 1.0e6f;
            g_kf.event_angle_rad = g_kf.event_min_rad = g_kf.event_max_rad = 0.0f;
        }
        hd_kf_output_t out;
        hd_mark_begin();
        hd_kf_step(&g_kf, &in, &out);
        hd_mark_end();
    }
    if (path == PATH_ROLLBACK && g_kf.rollback_count != CALLS) {
        sh_exit(BOARD_EXIT_INIT); /* the path was not the one measured */
    }
}

static void push_frame(const hal_can_frame_t *f)
{
    (void)hal_mock_push_rx(&g_mock, f);
}

/* The control frames of tick k: a TORQUE SETPOINT and a GAINS frame. */
/* ident: at tick 0 an IDENT_START (a long run at 0.05 A rms: its peak far
 * from the current limit, so the run lasts the section) instead of GAINS. */
static void push_control(const hd_fw_config_t *cfg, uint32_t k, bool ident)
{
    const hd_can_setpoint_t sp = {HD_CTRL_TORQUE, (uint8_t)k, 2.0f + 0.01f * (float)(k % 50u),
                                  0.0f, 0.0f};
    hal_can_frame_t f;
    hd_can_encode_setpoint(cfg->node_id, &sp, &f);
    push_frame(&f);
    if (ident && k == 0u) {
        hd_can_cmd_t cmd;
        memset(&cmd, 0, sizeof cmd);
        cmd.opcode = HD_CMD_IDENT_START;
        cmd.arg.ident_start.periods = 60u;
        cmd.arg.ident_start.rms_a = 0.05f;
        hd_can_encode_cmd(cfg->node_id, &cmd, &f);
        push_frame(&f);
        return;
    }
    const hd_can_gains_t g = {50.0f + (float)(k % 7u), 1.0f};
    hd_can_encode_gains(cfg->node_id, &g, &f);
    push_frame(&f);
}

/* control: a drive in the HAL (the control stage runs); with commands,
 * one SETPOINT at tick 0 and the command frames on the other ticks. */
static void bench_isr(const hd_fw_config_t *cfg, unsigned commands_per_tick, bool control,
                      bool ident)
{
    hal_mock_init(&g_mock);
    hal_mock_bind(&g_mock, &g_hal);
    if (control) {
        hd_ls_bind_drive(&g_drive, &g_hal);
    }
    g_mock.auto_advance_us = 0u;
    g_mock.tx_store = false; /* frames are "sent" (counted), as to a CAN mailbox */
    if (hd_fw_init(&g_fw, &g_hal, cfg) != HD_FW_OK) {
        sh_exit(BOARD_EXIT_INIT);
    }
    const float volts_per_nm = 1.0f / 6.60f; /* Table I: 6.60 Nm/V */
    const float counts_per_rad = (float)cfg->motor_cpr / HD_TWO_PI_F;
    float angle = 0.0f;
    float counts_f = 0.0f;
    for (uint32_t k = 0; k < CALLS; k++) {
        float torque = test_torque_nm(k, angle);
        int32_t counts = (int32_t)(torque * volts_per_nm / cfg->adc_volts_per_count);
        (void)hal_mock_push(&g_mock, counts, (uint32_t)(int32_t)counts_f);
        if (control && (commands_per_tick == 0u || k == 0u)) {
            push_control(cfg, k, ident);
        }
        for (unsigned c = 0; c < ((control && k == 0u) ? 0u : commands_per_tick); c++) {
            hd_can_cmd_t cmd;
            memset(&cmd, 0, sizeof cmd);
            cmd.token = (uint8_t)c;
            if (c == 0u) {
                cmd.opcode = HD_CMD_BLOCK_ENABLE; /* applied by the tick itself */
                cmd.arg.block_enable.index = 0u;
                cmd.arg.block_enable.enable = (uint8_t)(k & 1u);
            } else if (control && (k & 2u) != 0u) {
                /* a new law every other tick: the control stage restarts it */
                cmd.opcode = HD_CMD_SET_PARAM;
                cmd.arg.set_param.id = HD_PARAM_CTRL_DAMP_NM_S_RAD;
                cmd.arg.set_param.value = cfg->ctrl.damp_nm_s_rad + (float)(k & 4u);
            } else {
                cmd.opcode = HD_CMD_SET_PARAM;
                cmd.arg.set_param.id = HD_PARAM_R_NM2;
                cmd.arg.set_param.value = cfg->kf.r_nm2; /* a rebuild of the same model */
            }
            hal_can_frame_t f;
            hd_can_encode_cmd(cfg->node_id, &cmd, &f);
            (void)hal_mock_push_rx(&g_mock, &f);
        }
        g_mock.now_us = (uint64_t)k * HD_FW_TS_US;
        hd_mark_begin();
        hd_fw_isr(&g_fw);
        hd_mark_end();
        (void)hd_fw_background(&g_fw); /* the main loop's share, not the tick's */
        float d = MOTOR_SPEED_RAD_S * HD_FW_TS_S;
        angle += d;
        wrap_angle(&angle);
        counts_f += d * counts_per_rad;
        if (counts_f > 1.0e6f) {
            counts_f -= 1.0e6f; /* keep float resolution; a count jump only at the wrap */
        }
    }
}

/* hd_ctrl_step alone: the modes in turn, speeds and angles that reach the
 * velocity limit, the position window and the current limit. */
static void bench_ctrl(const hd_fw_config_t *fw_cfg)
{
    static const hd_ctrl_mode_t MODES_RUN[] = {HD_CTRL_TORQUE, HD_CTRL_IMPEDANCE,
                                               HD_CTRL_ZERO_TORQUE, HD_CTRL_DAMP};
    static hd_ctrl_t ctrl;
    static hd_ctrl_plan_t plan;
    hd_ctrl_config_t cfg;
    hd_fw_ctrl_config(fw_cfg, &cfg);
    cfg.position_min_rad = -0.5f;
    cfg.position_max_rad = 0.5f;
    if (hd_ctrl_init(&ctrl, &plan, &cfg) != HD_CTRL_OK) {
        sh_exit(BOARD_EXIT_INIT);
    }
    for (uint32_t k = 0; k < CALLS; k++) {
        const float u = (float)(k % 16u) / 16.0f; /* 0 .. 15/16 */
        const hd_ctrl_setpoint_t sp = {MODES_RUN[k % 4u], 30.0f * u - 10.0f, 0.8f * u - 0.2f,
                                       0.5f, 200.0f * u, 2.0f};
        const hd_ctrl_input_t in = {.torque_filtered_nm = 5.0f * u, .torque_raw_nm = 5.5f * u,
                                    .torque_valid = true, .angle_rad = 1.2f * u - 0.6f,
                                    .velocity_rad_s = 12.0f * u - 6.0f};
        hd_ctrl_output_t out;
        hd_mark_begin();
        hd_ctrl_step(&ctrl, &sp, &in, &out);
        hd_mark_end();
    }
}

int main(void)
{
    hd_mark_calibration(calibration_section);

    for (unsigned m = 0; m < sizeof MODELS / sizeof MODELS[0]; m++) {
        hd_fw_config_t cfg;
        model_config(&MODELS[m], &cfg);
        uint32_t states = 2u * cfg.kf.block_count + (cfg.kf.offset_enabled ? 1u : 0u);

        section("kf", MODELS[m].name, states);
        bench_kf(&cfg);
        hd_mark_section();

        section("isr", MODELS[m].name, states);
        bench_isr(&cfg, 0u, false, false);
        hd_mark_section();

        section("isrcmd", MODELS[m].name, states);
        bench_isr(&cfg, HD_FW_RX_PER_TICK, false, false);
        hd_mark_section();

        section("isrctrl", MODELS[m].name, states);
        bench_isr(&cfg, 0u, true, false);
        hd_mark_section();

        section("isrident", MODELS[m].name, states);
        bench_isr(&cfg, 0u, true, true);
        if (!g_fw.ident.running) { /* the section measured a run, or it says so */
            sh_puts("bench: the identification run did not run\n");
            sh_exit(BOARD_EXIT_INIT);
        }
        hd_mark_section();

        section("isrctrlcmd", MODELS[m].name, states);
        bench_isr(&cfg, HD_FW_RX_PER_TICK, true, false);
        hd_mark_section();

        section("dense", MODELS[m].name, states);
        bench_dense(&cfg);
        hd_mark_section();

        static const char *const PATHS[] = {"kffrozen", "kflost",   "kfclamp",   "kfreset",
                                            "kfworst",  "kfpartial", "kfrollback"};
        for (unsigned p = 0; p < sizeof PATHS / sizeof PATHS[0]; p++) {
            section(PATHS[p], MODELS[m].name, states);
            bench_kf_path(&cfg, (kf_path_t)p);
            hd_mark_section();
        }
    }
    hd_fw_config_t dflt;
    hd_fw_config_default(&dflt);
    section("ctrl", "default", 2u * dflt.kf.block_count + (dflt.kf.offset_enabled ? 1u : 0u));
    bench_ctrl(&dflt);
    hd_mark_section();
    sh_puts("bench: done\n");
    return BOARD_EXIT_OK;
}

/* No SysTick in the bench image. */
void SysTick_Handler(void)
{
}
