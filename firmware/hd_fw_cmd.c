/* hd_fw_cmd: the command plane, run by hd_fw_background.  Each command is
 * decoded, executed against a copy of the live settings, and its result
 * handed to the tick as one request (hd_fw.h, "two contexts"): the tick
 * swaps it in between two samples.  Commands run strictly in order; the
 * next one waits until the tick has taken the previous change, so a
 * CONFIG_SAVE after a SET_PARAM saves the new value. */
#include <stdatomic.h>
#include <string.h>

#include "hd_fw.h"
#include "hd_fw_internal.h"
#include "hd_fw_records.h"
#include "hd_params.h"

typedef struct {
    int result;       /* hd_can_result_t */
    uint8_t aux;
    float value;
    uint32_t value_u32;
    bool deferred;    /* the ACK is queued later (PROFILE_SAVE of the running filter) */
} reply_t;

static void queue_ack(hd_fw_t *fw, uint8_t node, const hd_can_cmd_t *cmd, const reply_t *r);

/* ---------------------------------------------------------------- helpers */

static void post(hd_fw_t *fw, uint8_t flags, uint8_t block, uint8_t enable)
{
    hd_fw_request_t *r = &fw->request;
    r->flags = flags;
    r->block = block;
    r->enable = enable;
    atomic_signal_fence(memory_order_release); /* the fields before pending */
    r->pending = 1u;
}

/* Makes next the running configuration.  rebuild: a new pipeline (the
 * filter restarts), else the live one keeps its state.  Refused models
 * leave everything as it was. */
static int commit_with(hd_fw_t *fw, const hd_fw_settings_t *next, bool rebuild, uint8_t extra)
{
    const hd_fw_config_t *c = &next->cfg;
    if (hd_fw_config_check(c, NULL) != HD_FW_OK) {
        return HD_CAN_RES_REJECTED;
    }
    hd_pipeline_t *spare_pipe = &fw->pipe[(fw->live_pipe & 1u) ^ 1u];
    if (rebuild && hd_fw_pipeline_init(spare_pipe, c) != HD_KF_OK) {
        return HD_CAN_RES_REJECTED;
    }
    hd_fw_settings_t *spare = hd_fw_spare(fw);
    *spare = *next;
    hd_fw_derive_next(fw, spare);
    post(fw, (uint8_t)(HD_FW_REQ_SETTINGS | (rebuild ? HD_FW_REQ_PIPE : 0u) | extra), 0u, 0u);
    return HD_CAN_RES_OK;
}

static int commit(hd_fw_t *fw, const hd_fw_settings_t *next, bool rebuild)
{
    return commit_with(fw, next, rebuild, 0u);
}

static int result_of(hd_fw_err_t e)
{
    switch (e) {
    case HD_FW_OK: return HD_CAN_RES_OK;
    case HD_FW_ERR_UNKNOWN_PARAM: return HD_CAN_RES_UNKNOWN_PARAM;
    case HD_FW_ERR_READ_ONLY: return HD_CAN_RES_READ_ONLY;
    case HD_FW_ERR_NOT_FINITE: return HD_CAN_RES_NOT_FINITE;
    default: return HD_CAN_RES_OUT_OF_RANGE;
    }
}

/* ------------------------------------------------------------ parameters */

static void set_param(hd_fw_t *fw, uint8_t id, float v, reply_t *r)
{
    const hd_param_info_t *p = hd_param_by_id(id);
    r->aux = id;
    hd_fw_settings_t next = *hd_fw_live(fw);
    r->result = result_of(hd_param_set(p, &next.cfg, v));
    if (r->result == HD_CAN_RES_OK) {
        r->result = commit(fw, &next, (p->flags & HD_PF_REBUILD) != 0u);
        if (r->result == HD_CAN_RES_OK && id == HD_PARAM_NODE_ID) {
            hd_fw_set_rx_filter(fw, next.cfg.node_id);
        }
    }
    /* The value now in force (the new one, or the old one if refused). */
    const hd_fw_settings_t *now = (r->result == HD_CAN_RES_OK) ? &next : hd_fw_live(fw);
    r->value = (p != NULL) ? hd_param_get(p, &now->cfg) : 0.0f;
}

static void get_param(const hd_fw_t *fw, uint8_t id, reply_t *r)
{
    const hd_param_info_t *p = hd_param_by_id(id);
    r->aux = id;
    if (p == NULL) {
        r->result = HD_CAN_RES_UNKNOWN_PARAM;
        return;
    }
    r->value = hd_param_get(p, &hd_fw_live(fw)->cfg);
}

/* ------------------------------------------------------------ the model */

static void add_block(hd_fw_t *fw, const hd_can_cmd_t *cmd, reply_t *r)
{
    hd_fw_settings_t next = *hd_fw_live(fw);
    hd_kf_config_t *kf = &next.cfg.kf;
    float order = cmd->arg.add_fixed.frequency_hz;
    float q_nm2 = cmd->arg.add_fixed.q_nm2;
    if (cmd->opcode == HD_CMD_ADD_MOTOR) {
        order = cmd->arg.add_motor.order;
        q_nm2 = cmd->arg.add_motor.q_nm2;
    } else if (cmd->opcode == HD_CMD_ADD_OUTPUT) {
        order = cmd->arg.add_output.order;
        q_nm2 = cmd->arg.add_output.q_nm2;
    }
    if (!(order > 0.0f) || !(q_nm2 >= 0.0f) ||
        (cmd->opcode == HD_CMD_ADD_FIXED && order >= 0.5f / HD_FW_TS_S)) {
        r->result = HD_CAN_RES_OUT_OF_RANGE;
        return;
    }
    if (kf->block_count >= HD_KF_MAX_BLOCKS) {
        r->result = HD_CAN_RES_NO_SPACE;
        return;
    }
    hd_kf_block_config_t *b = &kf->blocks[kf->block_count];
    b->lock = (uint8_t)(cmd->opcode - HD_CMD_ADD_MOTOR); /* MOTOR, OUTPUT, FIXED in order */
    b->enabled = 1u;
    b->order = order;
    b->q_nm2 = q_nm2;
    r->aux = kf->block_count;
    kf->block_count++;
    r->result = commit(fw, &next, true);
}

/* Other blocks keep their estimates: the tick toggles the block in the
 * live filter while the settings record the new state. */
static void block_enable(hd_fw_t *fw, const hd_can_cmd_t *cmd, reply_t *r)
{
    hd_fw_settings_t next = *hd_fw_live(fw);
    const hd_can_cmd_block_enable_t *a = &cmd->arg.block_enable;
    const uint8_t i = a->index;
    r->aux = i;
    if (i >= next.cfg.kf.block_count) {
        r->result = HD_CAN_RES_BAD_INDEX;
        return;
    }
    if (a->enable > 1u) {
        r->result = HD_CAN_RES_OUT_OF_RANGE;
        return;
    }
    next.cfg.kf.blocks[i].enabled = a->enable;
    if (hd_fw_config_check(&next.cfg, NULL) != HD_FW_OK) {
        r->result = HD_CAN_RES_REJECTED;
        return;
    }
    hd_fw_settings_t *spare = hd_fw_spare(fw);
    *spare = next;
    hd_fw_derive_next(fw, spare);
    post(fw, HD_FW_REQ_SETTINGS | HD_FW_REQ_BLOCK, i, a->enable);
}

/* BLOCK_GET: one field of a configured block, so a host can read a model
 * back (hdsense send). */
static void block_get(const hd_fw_t *fw, const hd_can_cmd_t *cmd, reply_t *r)
{
    const hd_kf_config_t *kf = &hd_fw_live(fw)->cfg.kf;
    const uint8_t i = cmd->arg.block_get.index;
    r->aux = i;
    if (i >= kf->block_count) {
        r->result = HD_CAN_RES_BAD_INDEX;
        return;
    }
    const hd_kf_block_config_t *b = &kf->blocks[i];
    switch (cmd->arg.block_get.field) {
    case HD_BLOCK_FIELD_LOCK: r->value = (float)b->lock; break;
    case HD_BLOCK_FIELD_ORDER: r->value = b->order; break;
    case HD_BLOCK_FIELD_Q_NM2: r->value = b->q_nm2; break;
    case HD_BLOCK_FIELD_ENABLED: r->value = (float)b->enabled; break;
    default: r->result = HD_CAN_RES_OUT_OF_RANGE; break;
    }
}

static void blocks_clear(hd_fw_t *fw, reply_t *r)
{
    hd_fw_settings_t next = *hd_fw_live(fw);
    next.cfg.kf.block_count = 0u;
    r->result = commit(fw, &next, true);
}

/* --------------------------------------------------------- calibration */

static void tare(hd_fw_t *fw, reply_t *r)
{
    const hd_fw_gauge_t *k = &fw->gauge;
    uint32_t n = k->tare_n;
    if (n == 0u) {
        r->result = HD_CAN_RES_NO_DATA;
        return;
    }
    /* Summed afresh (bounded: 64 adds) so no running sum drifts. */
    float sum = 0.0f;
    for (uint32_t i = 0; i < n; i++) {
        sum += k->tare_v[i];
    }
    hd_fw_settings_t next = *hd_fw_live(fw);
    next.cfg.calib_offset_v = sum / (float)n;
    r->value = next.cfg.calib_offset_v;
    r->result = commit(fw, &next, false);
}

static void calib_job(hd_fw_t *fw, const hd_can_cmd_t *cmd, reply_t *r)
{
    hd_fw_settings_t next = *hd_fw_live(fw);
    r->result = (cmd->opcode == HD_CMD_CALIB_SAVE)
                    ? hd_fw_calib_save(fw, cmd->arg.calib_save.calibrated_unix_s, &next)
                    : hd_fw_calib_load(fw, &next, &r->aux, &r->value);
    if (r->result == HD_CAN_RES_OK) {
        r->result = commit(fw, &next, false);
    }
}

/* ------------------------------------------------------- configuration */

/* A configuration from the record or the defaults replaces the model but
 * not the calibration, which has its own record. */
static void config_replace(hd_fw_t *fw, const hd_fw_config_t *cfg, uint8_t status, reply_t *r)
{
    const hd_fw_settings_t *live = hd_fw_live(fw);
    hd_fw_settings_t next = *live;
    next.cfg = *cfg;
    next.cfg.calib_gain_nm_per_v = live->cfg.calib_gain_nm_per_v;
    next.cfg.calib_offset_v = live->cfg.calib_offset_v;
    next.config_status = status;
    next.record_faults &= ~(uint32_t)HD_FAULT_CONFIG_DEFAULTS;
    r->result = commit(fw, &next, true);
    if (r->result == HD_CAN_RES_OK && next.cfg.node_id != live->cfg.node_id) {
        hd_fw_set_rx_filter(fw, next.cfg.node_id);
    }
}

static void config_job(hd_fw_t *fw, uint8_t opcode, reply_t *r)
{
    if (opcode == HD_CMD_CONFIG_SAVE) {
        r->result = hd_fw_config_save(fw, &r->aux);
        if (r->result == HD_CAN_RES_OK) {
            hd_fw_settings_t next = *hd_fw_live(fw);
            next.config_status = HD_RECORD_OK;
            next.record_faults &= ~(uint32_t)HD_FAULT_CONFIG_DEFAULTS;
            r->result = commit(fw, &next, false);
        }
        return;
    }
    hd_fw_config_t cfg;
    if (opcode == HD_CMD_CONFIG_LOAD) {
        r->result = hd_fw_config_load(fw, &cfg, &r->aux);
        if (r->result == HD_CAN_RES_OK) {
            config_replace(fw, &cfg, r->aux, r);
        }
        return;
    }
    config_replace(fw, hd_fw_boot_defaults(fw), hd_fw_live(fw)->config_status, r);
}

/* ---------------------------------------------------------- information */

static void info(const hd_fw_t *fw, const hd_can_cmd_t *cmd, reply_t *r)
{
    const uint8_t item = (cmd->opcode == HD_CMD_VERSION) ? cmd->arg.version.item
                                                         : cmd->arg.info.item;
    r->aux = item;
    /* VERSION answers the items below 16, INFO the rest. */
    bool mine = (cmd->opcode == HD_CMD_VERSION) ? item < 16u : item >= 16u;
    if (!mine || !hd_fw_info_item(fw, item, &r->value_u32)) {
        r->result = HD_CAN_RES_BAD_INDEX;
    }
}

static void reboot(hd_fw_t *fw, reply_t *r)
{
    if (fw->hal->system.reboot == NULL) {
        r->result = HD_CAN_RES_UNSUPPORTED;
        return;
    }
    fw->bg.reboot_pending = 1u; /* once the ACK is out */
}

/* -------------------------------------------------------------- profiles */

#define PUT_INDEX_MASK 0x0Fu
#define PUT_B 0x10u
#define PUT_OUTPUT 0x20u
#define PUT_RESERVED 0xC0u

static uint16_t lines_mask(unsigned lines)
{
    return (uint16_t)((1u << (2u * lines)) - 1u);
}

static bool upload_complete(const hd_fw_t *fw)
{
    const unsigned n = fw->bg.upload.line_count;
    return n > 0u && fw->bg.upload_mask == lines_mask(n);
}

/* Lines arrive in order, a before b: line 0's a starts a new upload. */
static void profile_put(hd_fw_t *fw, const hd_can_cmd_t *cmd, reply_t *r)
{
    const hd_can_cmd_profile_put_t *a = &cmd->arg.profile_put;
    const uint8_t b2 = a->line;
    const unsigned i = b2 & PUT_INDEX_MASK;
    const bool is_b = (b2 & PUT_B) != 0u;
    const uint8_t lock = (b2 & PUT_OUTPUT) != 0u ? HD_KF_LOCK_OUTPUT : HD_KF_LOCK_MOTOR;
    const uint8_t order = a->order;
    const float v = a->value_nm; /* not checked by the decoder: after the index, below */
    r->aux = b2;
    r->value = v;
    const float lim = hd_fw_live(fw)->cfg.torque_limit_nm;
    if ((b2 & PUT_RESERVED) != 0u || i >= HD_KF_MAX_BLOCKS) {
        r->result = HD_CAN_RES_BAD_INDEX;
        return;
    }
    if (!(v - v == 0.0f)) {
        r->result = HD_CAN_RES_NOT_FINITE;
        return;
    }
    if (order == 0u || v > lim || v < -lim) {
        r->result = HD_CAN_RES_OUT_OF_RANGE;
        return;
    }
    hd_kf_profile_t *u = &fw->bg.upload;
    if (i == 0u && !is_b) {
        memset(u, 0, sizeof *u);
        fw->bg.upload_mask = 0u;
    }
    const uint16_t before = is_b ? (uint16_t)(lines_mask(i) | (1u << (2u * i))) : lines_mask(i);
    hd_kf_profile_line_t *l = &u->lines[i];
    if (fw->bg.upload_mask != before || (is_b && (l->lock != lock || l->order != order))) {
        r->result = HD_CAN_RES_BAD_INDEX; /* out of order, or b for another line */
        return;
    }
    l->lock = lock;
    l->order = order;
    if (is_b) {
        l->b_nm = v;
    } else {
        l->a_nm = v;
        u->line_count = (uint8_t)(i + 1u);
    }
    fw->bg.upload_mask = (uint16_t)(before | (1u << (2u * i + (is_b ? 1u : 0u))));
}

/* PROFILE_SAVE / LOAD's source byte: 0 the filter or the record, 1 the
 * upload (which must be complete).  Returns false with r->result set if
 * the command cannot go on. */
static uint8_t source_of(const hd_can_cmd_t *cmd)
{
    return cmd->opcode == HD_CMD_PROFILE_SAVE ? cmd->arg.profile_save.source
                                              : cmd->arg.profile_load.source;
}

static bool profile_source(const hd_fw_t *fw, const hd_can_cmd_t *cmd, reply_t *r)
{
    const uint8_t source = source_of(cmd);
    if (source > 1u) {
        r->result = HD_CAN_RES_OUT_OF_RANGE;
        return false;
    }
    if (source == 1u && !upload_complete(fw)) {
        r->result = HD_CAN_RES_NO_DATA;
        return false;
    }
    return true;
}

static void profile_save(hd_fw_t *fw, const hd_can_cmd_t *cmd, uint8_t node, reply_t *r)
{
    if (!profile_source(fw, cmd, r)) {
        return;
    }
    if (source_of(cmd) == 1u) {
        hd_fw_settings_t next = *hd_fw_live(fw);
        r->value = (float)fw->bg.upload.line_count;
        r->result = hd_fw_profile_save(fw, &fw->bg.upload, &next, &r->aux);
        if (r->result == HD_CAN_RES_OK) {
            r->result = commit(fw, &next, false);
        }
        return;
    }
    /* The tick exports the filter at its next boundary; the save and the
     * ACK follow in a later background call (finish_profile_save). */
    fw->bg.save_pending = true;
    fw->bg.save_cmd = *cmd;
    fw->bg.save_node = node;
    fw->bg.save_snapshot_seq = fw->filter.snapshot_seq;
    post(fw, HD_FW_REQ_SNAPSHOT, 0u, 0u);
    r->deferred = true;
}

static void profile_load(hd_fw_t *fw, const hd_can_cmd_t *cmd, reply_t *r)
{
    hd_fw_settings_t next = *hd_fw_live(fw);
    if (!profile_source(fw, cmd, r)) {
        return;
    }
    if (source_of(cmd) == 1u) {
        fw->bg.profile = fw->bg.upload;
        r->aux = next.profile_status;
        r->value = (float)fw->bg.profile.line_count;
        post(fw, HD_FW_REQ_PROFILE, 0u, 0u);
        return;
    }
    r->result = hd_fw_profile_load(fw, &next, &r->aux);
    if (r->result == HD_CAN_RES_OK) {
        r->value = (float)fw->bg.profile.line_count;
        r->result = commit_with(fw, &next, false, HD_FW_REQ_PROFILE);
    }
}

static void profile_clear(hd_fw_t *fw, reply_t *r)
{
    hd_fw_settings_t next = *hd_fw_live(fw);
    r->result = hd_fw_profile_clear(fw, &next, &r->aux);
    if (r->result == HD_CAN_RES_OK) {
        r->result = commit(fw, &next, false);
    }
}

static void profile_job(hd_fw_t *fw, const hd_can_cmd_t *cmd, uint8_t node, reply_t *r)
{
    if (cmd->opcode != HD_CMD_PROFILE_PUT &&
        (fw->filter.import_pending || fw->filter.snapshot_pending)) {
        r->result = HD_CAN_RES_BUSY; /* the tick still reads bg.profile (no encoder yet) */
        return;
    }
    switch (cmd->opcode) {
    case HD_CMD_PROFILE_SAVE: profile_save(fw, cmd, node, r); break;
    case HD_CMD_PROFILE_LOAD: profile_load(fw, cmd, r); break;
    case HD_CMD_PROFILE_CLEAR: profile_clear(fw, r); break;
    default: profile_put(fw, cmd, r); break;
    }
}

/* A PROFILE_SAVE of the running filter, once the tick has taken the
 * snapshot: save it and send the ACK.  Returns true if it finished. */
static bool finish_profile_save(hd_fw_t *fw)
{
    hd_fw_bg_state_t *b = &fw->bg;
    if (!b->save_pending || fw->request.pending || fw->filter.snapshot_seq == b->save_snapshot_seq ||
        hd_fw_queue_full(&fw->ack_queue)) {
        return false;
    }
    b->save_pending = false;
    const hd_kf_profile_t snap = fw->filter.snapshot; /* the tick writes it only on request */
    reply_t r = {HD_CAN_RES_OK, 0u, (float)snap.line_count, 0u, false};
    if (snap.line_count == 0u) {
        r.result = HD_CAN_RES_NO_DATA; /* no profile-able block, or no absolute angle */
    } else {
        hd_fw_settings_t next = *hd_fw_live(fw);
        r.result = hd_fw_profile_save(fw, &snap, &next, &r.aux);
        if (r.result == HD_CAN_RES_OK) {
            r.result = commit(fw, &next, false);
        }
    }
    queue_ack(fw, b->save_node, &b->save_cmd, &r);
    return true;
}

/* ------------------------------------------------------------- dispatch */

static void ident_start(hd_fw_t *fw, const hd_can_cmd_ident_start_t *a, reply_t *r)
{
    r->aux = a->periods;
    r->result = hd_fw_ident_prepare(fw, a, &r->value);
    if (r->result == HD_CAN_RES_OK) {
        post(fw, HD_FW_REQ_IDENT, 0u, 0u);
    }
}

static void execute(hd_fw_t *fw, const hd_can_cmd_t *cmd, uint8_t node, reply_t *r)
{
    switch (cmd->opcode) {
    case HD_CMD_FILTER_ENABLE:
        set_param(fw, HD_PARAM_FILTER_ENABLED, cmd->arg.filter_enable.enable, r);
        break;
    case HD_CMD_ADD_MOTOR:
    case HD_CMD_ADD_OUTPUT:
    case HD_CMD_ADD_FIXED: add_block(fw, cmd, r); break;
    case HD_CMD_BLOCK_ENABLE: block_enable(fw, cmd, r); break;
    case HD_CMD_BLOCKS_CLEAR: blocks_clear(fw, r); break;
    case HD_CMD_BLOCK_GET: block_get(fw, cmd, r); break;
    case HD_CMD_SET_PARAM: set_param(fw, cmd->arg.set_param.id, cmd->arg.set_param.value, r); break;
    case HD_CMD_GET_PARAM: get_param(fw, cmd->arg.get_param.id, r); break;
    case HD_CMD_TARE: tare(fw, r); break;
    case HD_CMD_CALIB_SAVE:
    case HD_CMD_CALIB_LOAD: calib_job(fw, cmd, r); break;
    case HD_CMD_FILTER_RESET: post(fw, HD_FW_REQ_KF_RESET, 0u, 0u); break;
    case HD_CMD_CONFIG_SAVE:
    case HD_CMD_CONFIG_LOAD:
    case HD_CMD_CONFIG_DEFAULTS: config_job(fw, cmd->opcode, r); break;
    case HD_CMD_VERSION:
    case HD_CMD_INFO: info(fw, cmd, r); break;
    case HD_CMD_REBOOT: reboot(fw, r); break;
    case HD_CMD_PROFILE_SAVE:
    case HD_CMD_PROFILE_LOAD:
    case HD_CMD_PROFILE_CLEAR:
    case HD_CMD_PROFILE_PUT: profile_job(fw, cmd, node, r); break;
    case HD_CMD_IDENT_START: ident_start(fw, &cmd->arg.ident_start, r); break;
    default: r->result = HD_CAN_RES_UNKNOWN_OPCODE; break; /* the decoder checks first */
    }
}

static void queue_ack(hd_fw_t *fw, uint8_t node, const hd_can_cmd_t *cmd, const reply_t *r)
{
    hd_can_ack_t a = {cmd->opcode, cmd->token, (uint8_t)r->result, r->aux, r->value, r->value_u32};
    hal_can_frame_t f;
    hd_can_encode_ack(node, &a, &f);
    (void)hd_fw_queue_push(&fw->ack_queue, &f); /* room was checked before the command */
    if (r->result != HD_CAN_RES_OK) {
        fw->counters.command_errors++;
    }
}

void hd_fw_handle_frame(hd_fw_t *fw, const hal_can_frame_t *frame)
{
    /* The ACK goes out from the id the command reached (before a node change). */
    const uint8_t node = hd_fw_live(fw)->cfg.node_id;
    uint8_t type = 0u;
    uint8_t to = 0u;
    if ((frame->flags & HAL_CAN_FLAG_ERR) != 0u ||
        !hd_can_id_parse(frame->id, frame->flags, &type, &to) || to != node ||
        type != HD_CAN_FRAME_CMD) {
        return; /* not addressed to this node */
    }
    fw->counters.commands++;
    hd_can_cmd_t cmd;
    reply_t r = {hd_can_decode_cmd(frame, &cmd), 0u, 0.0f, 0u, false};
    if (r.result == HD_CAN_RES_OK && (fw->request.pending || fw->bg.save_pending)) {
        /* Only a caller that skips hd_fw_background's ordering gets here:
         * the tick has not taken the previous change yet. */
        r.result = HD_CAN_RES_BUSY;
    }
    if (r.result == HD_CAN_RES_OK) {
        execute(fw, &cmd, node, &r);
    }
    if (!r.deferred) {
        queue_ack(fw, node, &cmd, &r);
    }
}

bool hd_fw_background(hd_fw_t *fw)
{
    if (fw == NULL) {
        return false;
    }
    if (fw->bg.reboot_pending) {
        if (!hd_fw_queue_empty(&fw->ack_queue)) {
            return false;
        }
        fw->bg.reboot_pending = 0u;
        fw->hal->system.reboot(fw->hal->system.ctx);
        return true;
    }
    bool did = finish_profile_save(fw);
    for (unsigned i = 0; i < HD_FW_CMDS_PER_CALL; i++) {
        /* In order: wait for the tick to take the previous change, and for
         * room to answer. */
        if (fw->request.pending || hd_fw_queue_full(&fw->ack_queue) || fw->bg.reboot_pending ||
            fw->bg.save_pending) {
            break;
        }
        hal_can_frame_t f;
        if (!hd_fw_queue_pop(&fw->cmd_queue, &f)) {
            break;
        }
        hd_fw_handle_frame(fw, &f);
        did = true;
    }
    return did;
}
