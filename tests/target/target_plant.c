/*
 * target_plant: the host half of the closed-loop comparison (issue 23).
 *
 *   target_plant lockstep SAMPLES COMMANDS OUT.bin TICKS
 *       the plant for the QEMU image (firmware/board/mps2_an386/main_ctrl.c):
 *       opens the FIFO SAMPLES for writing, then COMMANDS for reading; per
 *       tick writes the sensors and the setpoint, reads the image's command,
 *       gives it to the simulated drive and integrates the joint; OUT.bin
 *       gets every command record received
 *   target_plant host OUT.bin TICKS
 *       the reference: the same firmware (host build) against the same
 *       plant in this process, through the same records and queues
 *
 * The plant: the dynamic joint (sim/hd_sim_joint defaults, a horizontal
 * link) against a spring (300 N m/rad, 5 N m s/rad) and the simulated drive
 * (hal/simdrive), its gauge through the nominal calibration (hal/simdyn);
 * the setpoint: TORQUE 0 N m, then TORQUE STEP_NM from tick STEP_TICK, a new
 * sequence number every tick.  Both modes write the same 28-byte records
 * (hd_lockstep.h); the files must be equal byte for byte.  Exit status 0, 1
 * on an exchange failure, 2 on a usage error.
 */
#include <stdio.h>
#include <stdlib.h>
#include <string.h>

#include "hal_mock.h"
#include "hal_simdyn.h"
#include "hd_calib_record.h"
#include "hd_fw.h"
#include "hd_lockstep.h"

#define STEP_TICK 300u
#define STEP_NM 10.0f

static hal_simdyn_t g_dyn;
static hal_t g_plant_hal; /* simdyn's sensors and drive, as the plant side sees them */

static int plant_init(void)
{
    hd_sim_joint_params_t jp;
    hd_sim_joint_default(&jp);
    jp.payload_kg = 0.0;
    jp.link_gravity_nm = 0.0;
    jp.env = HD_SIM_ENV_SPRING;
    jp.env_stiffness_nm_rad = 300.0;
    jp.env_damping_nm_s_rad = 5.0;
    hal_simdrive_config_t dc;
    hal_simdrive_default(&dc);
    hal_simdyn_sensor_t sc;
    hal_simdyn_sensor_default(&sc);
    sc.gain_nm_per_v = HD_CALIB_NOMINAL_GAIN_NM_PER_V; /* the firmware's default calibration */
    sc.offset_v = 0.0;
    char err[120];
    if (hal_simdyn_init(&g_dyn, &jp, &dc, &sc, err, sizeof err) != 0) {
        fprintf(stderr, "target_plant: %s\n", err);
        return -1;
    }
    memset(&g_plant_hal, 0, sizeof g_plant_hal);
    hal_simdyn_bind(&g_dyn, &g_plant_hal);
    return 0;
}

/* Tick k's sensors (the joint now) and setpoint. */
static void plant_sample(uint32_t k, uint32_t ticks, hd_ls_sample_t *s)
{
    memset(s, 0, sizeof *s);
    const hal_sensors_t *sen = &g_plant_hal.sensors;
    (void)sen->adc_read(sen->ctx, &s->sample.adc);
    (void)sen->encoder_read(sen->ctx, &s->sample.enc);
    s->mode = k < ticks ? (uint8_t)HD_CTRL_TORQUE : (uint8_t)HD_LS_END;
    s->seq = (uint8_t)k;
    s->torque_nm = k >= STEP_TICK ? STEP_NM : 0.0f;
}

/* The firmware's command of tick k to the drive, then the joint over it. */
static void plant_step(const uint8_t rec[HD_LS_COMMAND_BYTES])
{
    const hal_actuator_t *a = &g_plant_hal.actuator;
    const bool on = ((hd_ls_get32(&rec[4]) >> 8) & 1u) != 0u;
    (void)a->enable(a->ctx, on);
    if (on) {
        (void)a->command_current(a->ctx, hd_ls_float(hd_ls_get32(&rec[8])));
    }
    hal_simdyn_tick(&g_dyn);
}

static int run_host(FILE *out, uint32_t ticks)
{
    static hal_mock_t mock;
    static hd_fw_t fw;
    static hal_t hal;
    static hd_ls_drive_t drive;
    hal_mock_init(&mock);
    hal_mock_bind(&mock, &hal);
    mock.auto_advance_us = 0u;
    mock.tx_store = false;
    hd_ls_bind_drive(&drive, &hal);
    hd_fw_config_t cfg;
    hd_fw_config_default(&cfg);
    if (hd_fw_init(&fw, &hal, &cfg) != HD_FW_OK) {
        fprintf(stderr, "target_plant: firmware init failed\n");
        return 1;
    }
    for (uint32_t k = 0; k < ticks; k++) {
        hd_ls_sample_t s;
        plant_sample(k, ticks, &s);
        if (hd_ls_feed(&mock, &fw, &s, k) != 0) {
            fprintf(stderr, "target_plant: the mock's queues are full\n");
            return 1;
        }
        hd_fw_isr(&fw);
        (void)hd_fw_background(&fw);
        uint8_t rec[HD_LS_COMMAND_BYTES];
        hd_ls_pack_command(&fw, &drive, k, rec);
        if (fwrite(rec, sizeof rec, 1, out) != 1) {
            return 1;
        }
        plant_step(rec);
    }
    return 0;
}

static int run_lockstep(const char *samples, const char *commands, FILE *out, uint32_t ticks)
{
    FILE *to = fopen(samples, "wb");
    FILE *from = to != NULL ? fopen(commands, "rb") : NULL;
    if (to == NULL || from == NULL) {
        fprintf(stderr, "target_plant: cannot open the exchange FIFOs\n");
        return 1;
    }
    int rc = 0;
    for (uint32_t k = 0; k <= ticks && rc == 0; k++) {
        hd_ls_sample_t s;
        plant_sample(k, ticks, &s);
        uint8_t srec[HD_LS_SAMPLE_BYTES];
        hd_ls_pack_sample(&s, srec);
        if (fwrite(srec, sizeof srec, 1, to) != 1 || fflush(to) != 0) {
            rc = 1;
            break;
        }
        if (k == ticks) {
            break; /* the END record */
        }
        uint8_t crec[HD_LS_COMMAND_BYTES];
        if (fread(crec, sizeof crec, 1, from) != 1) {
            fprintf(stderr, "target_plant: the image stopped answering at tick %u\n",
                    (unsigned)k);
            rc = 1;
            break;
        }
        if (hd_ls_get32(&crec[0]) != k || fwrite(crec, sizeof crec, 1, out) != 1) {
            fprintf(stderr, "target_plant: command out of step at tick %u\n", (unsigned)k);
            rc = 1;
            break;
        }
        plant_step(crec);
    }
    fclose(to);
    fclose(from);
    return rc;
}

int main(int argc, char **argv)
{
    const bool lockstep = argc == 6 && strcmp(argv[1], "lockstep") == 0;
    const bool host = argc == 4 && strcmp(argv[1], "host") == 0;
    if (!lockstep && !host) {
        fprintf(stderr, "usage: target_plant lockstep SAMPLES COMMANDS OUT.bin TICKS\n"
                        "       target_plant host OUT.bin TICKS\n");
        return 2;
    }
    char *end = NULL;
    const unsigned long ticks = strtoul(argv[argc - 1], &end, 10);
    if (end == argv[argc - 1] || *end != '\0' || ticks == 0u || ticks > 1000000u) {
        fprintf(stderr, "target_plant: TICKS must be 1..1000000\n");
        return 2;
    }
    if (plant_init() != 0) {
        return 1;
    }
    FILE *out = fopen(argv[lockstep ? 4 : 2], "wb");
    if (out == NULL) {
        fprintf(stderr, "target_plant: cannot create %s\n", argv[lockstep ? 4 : 2]);
        return 1;
    }
    const int rc = lockstep ? run_lockstep(argv[2], argv[3], out, (uint32_t)ticks)
                            : run_host(out, (uint32_t)ticks);
    return (fclose(out) != 0 || rc != 0) ? 1 : 0;
}
