/* hd_emu: the firmware + mock HAL (CAN, NVM, system) + simulated joint
 * behind a small API for host tests (hd_emu.h).  Host only. */
#define _POSIX_C_SOURCE 200809L

#include "hd_emu.h"

#include <stdio.h>
#include <stdlib.h>
#include <string.h>

#include "hal_mock.h"
#include "hal_sim.h"
#include "hal_simdyn.h"
#include "hd_calib_record.h"
#include "hd_config_text.h"
#include "hd_fw.h"
#include "host_nvm.h"
#include "host_sim.h"

#define HD_EMU_RX_CAP 1024u
#define HD_EMU_TX_CAP 16384u
#define HD_EMU_BOARD_ID 0x30554D45u /* "EMU0", little-endian */

struct hd_emu {
    hal_mock_t mock;         /* CAN, NVM, system */
    hal_sim_t sim;           /* sensors, clock (the kinematic joint) */
    bool dynamic;            /* else: sensors, clock and drive from dyn */
    hal_simdyn_t dyn;
    hal_t hal;
    hd_fw_t fw;
    hd_fw_config_t defaults; /* firmware defaults + scenario constants + config text */
    uint64_t ticks;
    uint32_t boots;
    uint32_t reboots_seen;   /* mock.reboots already acted on */
    hd_emu_frame_t rx[HD_EMU_RX_CAP];
    uint32_t rx_head, rx_count;
    hd_emu_frame_t tx[HD_EMU_TX_CAP];
    uint32_t tx_head, tx_count;
    uint64_t tx_lost;
};

static void put_err(char *err, size_t err_len, const char *msg)
{
    if (err != NULL && err_len > 0u) {
        snprintf(err, err_len, "%s", msg);
    }
}

/* The mock's transmit hook: every frame the firmware sends, stamped with
 * the tick that sent it. */
static void on_tx(void *ctx, const hal_can_frame_t *f, uint64_t t_us)
{
    hd_emu_t *e = ctx;
    (void)t_us; /* the mock's clock is not ours: the sim's drives the firmware */
    if (e->tx_count == HD_EMU_TX_CAP) {
        e->tx_lost++;
        return;
    }
    hd_emu_frame_t *o = &e->tx[(e->tx_head + e->tx_count) % HD_EMU_TX_CAP];
    memset(o, 0, sizeof *o);
    o->t_us = e->ticks * HD_FW_TS_US;
    o->id = f->id;
    o->flags = f->flags;
    o->len = f->len > 8u ? 8u : f->len;
    memcpy(o->data, f->data, o->len);
    e->tx_count++;
}

static int store_nominal_calibration(hd_emu_t *e)
{
    if (e->dynamic) {
        return host_provision_calibration(&e->hal, (float)e->dyn.sens.gain_nm_per_v,
                                          (float)e->dyn.sens.offset_v);
    }
    hd_sim_nominal_t nom;
    hal_sim_nominal(&e->sim, &nom);
    return host_provision_calibration(&e->hal, (float)nom.gain_nm_per_v, (float)nom.offset_v);
}

static int boot(hd_emu_t *e, uint32_t reset_cause)
{
    memset(&e->mock.boot, 0, sizeof e->mock.boot);
    e->mock.boot.reset_cause = reset_cause;
    /* frames in the firmware's receive queue are lost with the RAM */
    e->mock.rx_count = 0u;
    e->mock.rx_head = 0u;
    if (hd_fw_init(&e->fw, &e->hal, &e->defaults) != HD_FW_OK) {
        return -1;
    }
    e->boots++;
    e->reboots_seen = e->mock.reboots;
    return 0;
}

/* The mock's CAN, NVM and system under the sensors bound before. */
static void bind_mock(hd_emu_t *e)
{
    hal_mock_init(&e->mock);
    e->mock.board_id = HD_EMU_BOARD_ID;
    e->mock.reboot_supported = true;
    e->mock.tx_store = false;
    e->mock.tx_hook = on_tx;
    e->mock.tx_hook_ctx = e;
    hal_mock_bind(&e->mock, &e->hal);
}

/* Applies config_text to e->defaults, stores the calibration, boots;
 * frees e on error. */
static hd_emu_t *finish(hd_emu_t *e, const char *config_text, char *err, size_t err_len)
{
    if (config_text != NULL) {
        hd_cfgtxt_error_t ce;
        if (hd_config_text_parse(config_text, strlen(config_text), &e->defaults, &ce) !=
            HD_FW_OK) {
            if (err != NULL && err_len > 0u) {
                snprintf(err, err_len, "config:%u: %s", ce.line, ce.message);
            }
            free(e);
            return NULL;
        }
    }
    if (store_nominal_calibration(e) != 0 || boot(e, HAL_RESET_POWER_ON) != 0) {
        put_err(err, err_len, "the firmware did not start (configuration refused)");
        free(e);
        return NULL;
    }
    return e;
}

hd_emu_t *hd_emu_create(const char *scenario_text, const char *config_text, char *err,
                        size_t err_len)
{
    hd_emu_t *e = calloc(1u, sizeof *e);
    if (e == NULL) {
        put_err(err, err_len, "out of memory");
        return NULL;
    }
    hd_sim_scenario_t sc;
    hd_sim_scenario_default(&sc);
    if ((scenario_text != NULL &&
         hd_sim_scenario_parse(&sc, scenario_text, "scenario", err, err_len) != 0) ||
        hal_sim_init(&e->sim, &sc, err, err_len) != 0) {
        free(e);
        return NULL;
    }
    if (sc.ts_s != 1e-3) {
        put_err(err, err_len, "scenario: ts_s must be 0.001 (the firmware's tick)");
        free(e);
        return NULL;
    }
    bind_mock(e);
    hal_sim_bind(&e->sim, &e->hal);
    e->hal.name = "emu";

    hd_fw_config_default(&e->defaults);
    hd_sim_nominal_t nom;
    hal_sim_nominal(&e->sim, &nom);
    host_sim_defaults(&nom, &e->defaults);
    return finish(e, config_text, err, err_len);
}

hd_emu_t *hd_emu_create_dynamic(const char *config_text, char *err, size_t err_len)
{
    hd_emu_t *e = calloc(1u, sizeof *e);
    if (e == NULL) {
        put_err(err, err_len, "out of memory");
        return NULL;
    }
    hd_sim_joint_params_t jp;
    hd_sim_joint_default(&jp);
    jp.payload_kg = 0.0;
    jp.link_gravity_nm = 0.0;
    jp.env = HD_SIM_ENV_SPRING; /* K = D = 0 until set: free */
    hal_simdrive_config_t dc;
    hal_simdrive_default(&dc);
    hal_simdyn_sensor_t sens;
    hal_simdyn_sensor_default(&sens);
    sens.gain_nm_per_v = HD_CALIB_NOMINAL_GAIN_NM_PER_V; /* the data sheet's bridge */
    sens.offset_v = 0.0;
    if (hal_simdyn_init(&e->dyn, &jp, &dc, &sens, err, err_len) != 0) {
        free(e);
        return NULL;
    }
    e->dynamic = true;
    bind_mock(e);
    hal_simdyn_bind(&e->dyn, &e->hal); /* sensors, clock, drive over the mock's */
    e->hal.name = "emu-dynamic";
    hd_fw_config_default(&e->defaults);
    e->defaults.adc_volts_per_count = (float)sens.volts_per_count;
    e->defaults.motor_cpr = sens.motor_cpr;
    e->defaults.output_cpr = sens.output_cpr;
    e->defaults.gear_ratio = (float)jp.gear_ratio;
    return finish(e, config_text, err, err_len);
}

static bool nonneg(double x)
{
    return x >= 0.0 && x <= 1e12; /* false for NaN */
}

int hd_emu_set_environment(hd_emu_t *emu, double stiffness_nm_rad, double damping_nm_s_rad,
                           double person_torque_nm)
{
    if (emu == NULL || !emu->dynamic || !nonneg(stiffness_nm_rad) ||
        !nonneg(damping_nm_s_rad) || !(person_torque_nm > -1e12 && person_torque_nm < 1e12)) {
        return -1;
    }
    emu->dyn.joint.p.env_stiffness_nm_rad = stiffness_nm_rad;
    emu->dyn.joint.p.env_damping_nm_s_rad = damping_nm_s_rad;
    emu->dyn.joint.person_torque_nm = person_torque_nm;
    return 0;
}

int hd_emu_truth(const hd_emu_t *emu, hd_emu_truth_t *out)
{
    if (emu == NULL || out == NULL || !emu->dynamic) {
        return -1;
    }
    const hd_sim_joint_truth_t *t = &emu->dyn.truth;
    *out = (hd_emu_truth_t){t->t_s, t->output_torque_nm, t->motor_torque_nm,
                            t->person_torque_nm, t->output_angle_rad, t->output_velocity_rad_s,
                            emu->dyn.drive.current_a};
    return 0;
}

void hd_emu_destroy(hd_emu_t *emu)
{
    free(emu);
}

static void feed_rx(hd_emu_t *e)
{
    while (e->rx_count > 0u) {
        const hd_emu_frame_t *s = &e->rx[e->rx_head];
        hal_can_frame_t f;
        memset(&f, 0, sizeof f);
        f.id = s->id;
        f.flags = s->flags;
        f.len = s->len;
        memcpy(f.data, s->data, s->len);
        if (hal_mock_push_rx(&e->mock, &f) != HAL_OK) {
            return; /* the driver's queue is full: the rest waits */
        }
        e->rx_head = (e->rx_head + 1u) % HD_EMU_RX_CAP;
        e->rx_count--;
    }
}

uint32_t hd_emu_tick(hd_emu_t *emu, uint32_t n)
{
    if (emu == NULL) {
        return 0u;
    }
    for (uint32_t i = 0; i < n; i++) {
        if (emu->fw.tick.ended) {
            return i;
        }
        feed_rx(emu);
        hd_fw_isr(&emu->fw);
        if (emu->fw.tick.ended) {
            return i;
        }
        emu->ticks++;
        (void)hd_fw_background(&emu->fw);
        if (emu->dynamic) {
            hal_simdyn_tick(&emu->dyn); /* the drive's tick, the joint over it */
        }
        if (emu->mock.reboots != emu->reboots_seen) {
            /* REBOOT: the ACK is out; the board restarts before the next tick */
            (void)boot(emu, HAL_RESET_SOFTWARE);
        }
    }
    return n;
}

int hd_emu_push_rx(hd_emu_t *emu, const hd_emu_frame_t *frame)
{
    if (emu == NULL || frame == NULL || frame->len > 8u || emu->rx_count == HD_EMU_RX_CAP) {
        return -1;
    }
    emu->rx[(emu->rx_head + emu->rx_count) % HD_EMU_RX_CAP] = *frame;
    emu->rx_count++;
    return 0;
}

int hd_emu_pop_tx(hd_emu_t *emu, hd_emu_frame_t *out)
{
    if (emu == NULL || out == NULL || emu->tx_count == 0u) {
        return 0;
    }
    *out = emu->tx[emu->tx_head];
    emu->tx_head = (emu->tx_head + 1u) % HD_EMU_TX_CAP;
    emu->tx_count--;
    return 1;
}

uint64_t hd_emu_tx_lost(const hd_emu_t *emu)
{
    return emu != NULL ? emu->tx_lost : 0u;
}

int hd_emu_power_cycle(hd_emu_t *emu, uint32_t reset_cause)
{
    return emu != NULL ? boot(emu, reset_cause) : -1;
}

uint8_t *hd_emu_nvm(hd_emu_t *emu, size_t *size)
{
    if (emu == NULL) {
        return NULL;
    }
    if (size != NULL) {
        *size = sizeof emu->mock.nvm;
    }
    return emu->mock.nvm;
}

uint64_t hd_emu_ticks(const hd_emu_t *emu)
{
    return emu != NULL ? emu->ticks : 0u;
}

uint32_t hd_emu_boots(const hd_emu_t *emu)
{
    return emu != NULL ? emu->boots : 0u;
}

int hd_emu_ended(const hd_emu_t *emu)
{
    return emu != NULL && emu->fw.tick.ended ? 1 : 0;
}
