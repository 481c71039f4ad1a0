/* hd_fw: boot, shared helpers and accessors; see hd_fw.h.  The tick is in
 * hd_fw_tick.c, the command plane in hd_fw_cmd.c, the records in
 * hd_fw_records.c. */
#include "hd_fw.h"

#include <stdatomic.h>
#include <string.h>

#include "hd_fw_internal.h"
#include "hd_trig.h"

void hd_fw_derive(hd_fw_settings_t *s)
{
    const hd_fw_config_t *c = &s->cfg;
    hd_ctrl_config_t ctrl;
    hd_fw_ctrl_config(c, &ctrl);
    /* hd_fw_config_check passed these settings: the plan is built */
    (void)hd_ctrl_plan(&s->ctrl, &ctrl);
    s->motor_rad_per_count = HD_TWO_PI_F / (float)c->motor_cpr;
    s->output_rad_per_count = HD_TWO_PI_F / (float)c->output_cpr;
    /* The most counts a healthy encoder can move in one tick, plus 2 counts
     * of quantisation margin; more than that is a glitch. */
    float motor_counts = c->max_motor_speed_rad_s * HD_FW_TS_S / s->motor_rad_per_count;
    float output_counts = motor_counts / c->gear_ratio * (float)c->output_cpr / (float)c->motor_cpr;
    s->max_motor_delta_counts = motor_counts > 1.0e9f ? 1000000000 : (int32_t)motor_counts + 2;
    s->max_output_delta_counts = output_counts > 1.0e9f ? 1000000000 : (int32_t)output_counts + 2;
    hd_slow_current_config(&s->current, &c->current, c->current_filter_hz, c->gear_ratio,
                           HD_FW_TS_S);
    s->telem_divider = (c->telemetry_rate_hz == 0u)
                           ? 0u
                           : (HD_FW_TICK_HZ + c->telemetry_rate_hz / 2u) / c->telemetry_rate_hz;
}

/* key starts with "ctrl_": a row of the law's configuration. */
static bool is_ctrl_key(const char *key)
{
    static const char prefix[] = "ctrl_"; /* the images link no strncmp */
    for (size_t i = 0; i + 1u < sizeof prefix; i++) {
        if (key[i] != prefix[i]) {
            return false;
        }
    }
    return true;
}

/* The control law is the same in both settings but perhaps for its motor
 * orders (which hd_ctrl_replan moves without a restart): every ctrl_*
 * parameter (hd_params.def: the law's configuration) and the gear ratio
 * hd_fw_ctrl_config takes from the rest.  Member by member, not the bytes
 * of hd_ctrl_config_t. */
static bool ctrl_unchanged(const hd_fw_settings_t *a, const hd_fw_settings_t *b)
{
    if (a->ctrl.cfg.gear_ratio != b->ctrl.cfg.gear_ratio) {
        return false;
    }
    for (size_t i = 0; i < hd_param_count(); i++) {
        const hd_param_info_t *p = hd_param_at(i);
        if (is_ctrl_key(p->key) && hd_param_get(p, &a->cfg) != hd_param_get(p, &b->cfg)) {
            return false;
        }
    }
    return true;
}

void hd_fw_derive_next(const hd_fw_t *fw, hd_fw_settings_t *spare)
{
    const hd_fw_settings_t *live = hd_fw_live(fw);
    hd_fw_derive(spare);
    spare->ctrl_gen = live->ctrl_gen + (ctrl_unchanged(spare, live) ? 0u : 1u);
}

/* ------------------------------------------------------------------ queues */

bool hd_fw_queue_push(hd_fw_queue_t *q, const hal_can_frame_t *f)
{
    if (hd_fw_queue_full(q)) {
        return false;
    }
    hd_fw_frame8_t *slot = &q->slot[q->head % HD_FW_QUEUE_LEN];
    slot->id = f->id;
    slot->len = f->len;
    slot->flags = f->flags;
    memcpy(slot->data, f->data, sizeof slot->data);
    atomic_signal_fence(memory_order_release); /* the slot is written before head moves */
    q->head = q->head + 1u;
    return true;
}

bool hd_fw_queue_pop(hd_fw_queue_t *q, hal_can_frame_t *f)
{
    if (hd_fw_queue_empty(q)) {
        return false;
    }
    const hd_fw_frame8_t *slot = &q->slot[q->tail % HD_FW_QUEUE_LEN];
    /* Only what a queued frame has: data beyond 8 bytes is never read. */
    f->id = slot->id;
    f->len = slot->len;
    f->flags = slot->flags;
    memcpy(f->data, slot->data, sizeof slot->data);
    atomic_signal_fence(memory_order_acq_rel); /* the slot is read before tail moves */
    q->tail = q->tail + 1u;
    return true;
}

/* -------------------------------------------------------------------- boot */

static int nvm_read(void *ctx, size_t offset, void *buf, size_t len)
{
    const hal_nvm_t *n = (const hal_nvm_t *)ctx;
    return n->read(n->ctx, offset, buf, len);
}

static int nvm_write(void *ctx, size_t offset, const void *buf, size_t len)
{
    const hal_nvm_t *n = (const hal_nvm_t *)ctx;
    return n->write(n->ctx, offset, buf, len);
}

static int nvm_erase(void *ctx, size_t offset, size_t len)
{
    const hal_nvm_t *n = (const hal_nvm_t *)ctx;
    return n->erase(n->ctx, offset, len);
}

hd_store_io_t hd_fw_store_io(const hal_t *hal, uint8_t *work, size_t work_size)
{
    hd_store_io_t io;
    memset(&io, 0, sizeof io);
    if (hal == NULL || hal->nvm.read == NULL) {
        return io; /* no NVM: every load is IO, every save fails */
    }
    io.ctx = (void *)&hal->nvm;
    io.size = hal->nvm.size;
    io.read = nvm_read;
    io.write = hal->nvm.write != NULL ? nvm_write : NULL;
    io.erase = hal->nvm.erase != NULL ? nvm_erase : NULL;
    io.work = work;
    io.work_size = work_size;
    return io;
}

int hd_fw_init(hd_fw_t *fw, const hal_t *hal, const hd_fw_config_t *defaults)
{
    if (fw == NULL || hal == NULL || defaults == NULL) {
        return HD_FW_ERR_NULL;
    }
    hd_fw_err_t rc = hd_fw_config_check(defaults, NULL);
    if (rc != HD_FW_OK) {
        return rc;
    }
    if (hal->sensors.adc_read == NULL) {
        return HD_FW_ERR_HAL;
    }
    memset(fw, 0, sizeof *fw);
    fw->hal = hal;
    fw->bg.defaults = *defaults;
    if (hal->system.boot_info != NULL) {
        hal->system.boot_info(hal->system.ctx, &fw->bg.boot);
    }
    hd_fw_settings_t *s = &fw->settings[0];
    hd_fw_records_boot(fw, defaults, s);
    hd_fw_derive(s);
    const hd_fw_config_t *c = &s->cfg;
    if (hd_fw_pipeline_init(&fw->pipe[0], c) != HD_KF_OK) {
        return HD_FW_ERR_KF; /* unreachable: records_boot only keeps checked configurations */
    }
    fw->settings[1] = *s;
    fw->tick.state = HD_STATE_INIT;
    /* The stored profile (if any) is taken by the first tick, at the
     * absolute angle of its sample. */
    fw->filter.import_pending = fw->bg.profile.line_count > 0u;
    hd_fw_set_rx_filter(fw, c->node_id);
    hd_fw_control_boot(fw);
    return HD_FW_OK;
}

int hd_fw_pipeline_init(hd_pipeline_t *p, const hd_fw_config_t *c)
{
    hd_kf_config_t kf;
    hd_fw_kf_config(c, &kf);
    return hd_pipeline_init(p, &kf, &c->expected, c->track_bandwidth_hz);
}

void hd_fw_set_rx_filter(const hd_fw_t *fw, uint8_t node_id)
{
    const hal_can_t *can = &fw->hal->can;
    if (can->set_rx_filter != NULL) {
        /* the control frames only with a drive (a board without one keeps
         * the filter it always had) */
        const uint32_t ids[4] = {
            hd_can_id(HD_CAN_FRAME_CMD, node_id) | HAL_CAN_ID_EXT_BIT,
            hd_can_id(HD_CAN_FRAME_FEEDFORWARD, node_id) | HAL_CAN_ID_EXT_BIT,
            hd_can_id(HD_CAN_FRAME_SETPOINT, node_id) | HAL_CAN_ID_EXT_BIT,
            hd_can_id(HD_CAN_FRAME_GAINS, node_id) | HAL_CAN_ID_EXT_BIT,
        };
        (void)can->set_rx_filter(can->ctx, ids, hd_fw_has_drive(fw) ? 4u : 2u);
    }
}

/* --------------------------------------------------------------- accessors */

const hd_fw_sample_t *hd_fw_last_sample(const hd_fw_t *fw)
{
    return &fw->last;
}

const hd_fw_counters_t *hd_fw_counters(const hd_fw_t *fw)
{
    return &fw->counters;
}

const hd_fw_config_t *hd_fw_config(const hd_fw_t *fw)
{
    return &hd_fw_live(fw)->cfg;
}

const hd_fw_config_t *hd_fw_boot_defaults(const hd_fw_t *fw)
{
    return &fw->bg.defaults;
}

int hd_fw_record_status(const hd_fw_t *fw, hd_record_kind_t kind)
{
    const hd_fw_settings_t *s = hd_fw_live(fw);
    switch (kind) {
    case HD_RECORD_KIND_CALIB: return s->calib_status;
    case HD_RECORD_KIND_CONFIG: return s->config_status;
    case HD_RECORD_KIND_PROFILE: return s->profile_status;
    default: return HD_RECORD_IO;
    }
}
