/*
 * Internal to the firmware core: what hd_fw.c, hd_fw_tick.c, hd_fw_cmd.c
 * and hd_fw_records.c share.  Not for users of hd_fw.h.
 */
#ifndef HD_FW_INTERNAL_H
#define HD_FW_INTERNAL_H

#include "hd_fw.h"

/* Settings the tick uses now, and the spare slot the background fills. */
static inline const hd_fw_settings_t *hd_fw_live(const hd_fw_t *fw)
{
    return &fw->settings[fw->live_settings & 1u];
}
static inline hd_fw_settings_t *hd_fw_spare(hd_fw_t *fw)
{
    return &fw->settings[(fw->live_settings & 1u) ^ 1u];
}
static inline hd_pipeline_t *hd_fw_live_pipe(hd_fw_t *fw)
{
    return &fw->pipe[fw->live_pipe & 1u];
}

/* Constants that follow from the configuration (glitch limits, telemetry
 * divider, angle per count). */
void hd_fw_derive(hd_fw_settings_t *s);
/* hd_fw_derive of the spare settings about to replace the live ones
 * (background), and their ctrl_gen: the live one's, plus 1 when the control
 * law's configuration differs in more than its motor orders, so the tick
 * restarts the law (a cleared loop) only then. */
void hd_fw_derive_next(const hd_fw_t *fw, hd_fw_settings_t *spare);

/* Asks the CAN driver for this node's command and feed-forward frames. */
void hd_fw_set_rx_filter(const hd_fw_t *fw, uint8_t node_id);

/* The queues: push returns false when full, pop when empty. */
bool hd_fw_queue_push(hd_fw_queue_t *q, const hal_can_frame_t *f);
bool hd_fw_queue_pop(hd_fw_queue_t *q, hal_can_frame_t *f);
static inline bool hd_fw_queue_full(const hd_fw_queue_t *q)
{
    return q->head - q->tail >= HD_FW_QUEUE_LEN;
}
static inline bool hd_fw_queue_empty(const hd_fw_queue_t *q)
{
    return q->head == q->tail;
}

/* The tick's stages (hd_fw_stages.h; tick context only), in the order
 * hd_fw_isr calls them; each returns the fault bits it raised.  The gauge
 * sets *faults and returns false when the sample source has ended. */
bool hd_fw_gauge(hd_fw_gauge_t *g, const hd_fw_config_t *c, const hal_sensors_t *sen,
                 uint64_t t_us, hd_fw_sample_t *s, uint32_t *faults);
uint32_t hd_fw_encoder(hd_fw_encoder_t *k, const hd_fw_settings_t *set, const hal_sensors_t *sen,
                       hd_fw_sample_t *s);
/* The absolute angles of the last sample, in [0, 2 pi). */
float hd_fw_encoder_motor_rad(const hd_fw_encoder_t *k, const hd_fw_settings_t *set);
float hd_fw_encoder_output_rad(const hd_fw_encoder_t *k, const hd_fw_settings_t *set);
uint32_t hd_fw_current(hd_fw_current_t *k, const hd_fw_config_t *c, const hal_sensors_t *sen,
                       hd_fw_sample_t *s);
/* Feed-forward: ages the latch (before the frames), takes one frame of
 * ours (counts it in *accepted), gives the sample its T_ff. */
void hd_fw_ff_age(hd_fw_ff_t *k);
uint32_t hd_fw_ff_take(hd_fw_ff_t *k, const hd_fw_config_t *c, const hal_can_frame_t *f,
                       uint32_t *accepted);
uint32_t hd_fw_ff(hd_fw_ff_t *k, const hd_fw_config_t *c, hd_fw_sample_t *s);
uint32_t hd_fw_filter(hd_fw_t *fw, hd_fw_sample_t *s);
void hd_fw_publish(hd_fw_t *fw, const hd_fw_sample_t *s);

/* hd_fw_control.c: a SETPOINT or GAINS frame of ours (the tick's receive
 * step), and the control stage after the pipeline; returns its faults. */
void hd_fw_take_control_frame(hd_fw_t *fw, const hal_can_frame_t *f, uint8_t type);
uint32_t hd_fw_control(hd_fw_t *fw, const hd_fw_sample_t *s, uint32_t faults);
/* The law built from the boot settings by hd_fw_init: the first tick does
 * not pay for it (the tick rebuilds it only when the settings change). */
void hd_fw_control_boot(hd_fw_t *fw);

/* hd_fw_ident.c.  Background: prepares a run (an HD_CAN_RES_*; *peak_a the
 * excitation's peak); the caller posts HD_FW_REQ_IDENT on HD_CAN_RES_OK. */
int hd_fw_ident_prepare(hd_fw_t *fw, const hd_can_cmd_ident_start_t *a, float *peak_a);
/* Tick: the request's start, and the current the drive is told this tick
 * (the law's, plus the excitation while a run is on). */
void hd_fw_ident_begin(hd_fw_ident_t *id);
float hd_fw_ident_drive(hd_fw_ident_t *id, const hd_ctrl_output_t *law, float current_limit_a);
/* A drive is present: the actuator part has enable and command_current
 * (inline: the tick asks up to three times). */
static inline bool hd_fw_has_drive(const hd_fw_t *fw)
{
    const hal_actuator_t *a = &fw->hal->actuator;
    return a->enable != NULL && a->command_current != NULL;
}
void hd_fw_stop(hd_fw_t *fw);

/* Records (hd_fw_records.c).  Boot: loads the calibration and configuration
 * records into *s (defaults and status where unusable). */
void hd_fw_records_boot(hd_fw_t *fw, const hd_fw_config_t *defaults, hd_fw_settings_t *s);
/* Background jobs; each returns an hd_can_result_t and fills *aux (record
 * status) and *value where the ACK carries one. */
int hd_fw_calib_save(hd_fw_t *fw, uint32_t unix_s, hd_fw_settings_t *next);
int hd_fw_calib_load(hd_fw_t *fw, hd_fw_settings_t *next, uint8_t *aux, float *value);
int hd_fw_config_save(hd_fw_t *fw, uint8_t *aux);
int hd_fw_config_load(hd_fw_t *fw, hd_fw_config_t *next, uint8_t *aux);
/* PROFILE_SAVE (lines into the record for next->cfg's joint), PROFILE_LOAD
 * (the record into bg.profile, checked against next->cfg), PROFILE_CLEAR;
 * each updates next's profile status and bg.profile on success. */
int hd_fw_profile_save(hd_fw_t *fw, const hd_kf_profile_t *lines, hd_fw_settings_t *next,
                       uint8_t *aux);
int hd_fw_profile_load(hd_fw_t *fw, hd_fw_settings_t *next, uint8_t *aux);
int hd_fw_profile_clear(hd_fw_t *fw, hd_fw_settings_t *next, uint8_t *aux);

/* hd_pipeline_init with the firmware's filter configuration (hd_fw_kf_config). */
int hd_fw_pipeline_init(hd_pipeline_t *p, const hd_fw_config_t *c);

/* The value of VERSION / INFO item `item` (HD_INFO_*) into *v; false for an
 * item this firmware does not have (hd_fw_info.c). */
bool hd_fw_info_item(const hd_fw_t *fw, uint8_t item, uint32_t *v);

/* The configuration hd_fw_init was given: CONFIG_DEFAULTS returns to it. */
const hd_fw_config_t *hd_fw_boot_defaults(const hd_fw_t *fw);

#endif /* HD_FW_INTERNAL_H */
