/* hd_fw: the firmware core; see hd_fw.h and docs/firmware.md. */
#include "hd_fw.h"

#include <math.h> /* isfinite, NAN: compiler builtins, no libm call */
#include <string.h>

#include "hd_trig.h"

#define TRACK_MAX_BANDWIDTH_HZ 79.0f /* hd_track needs 2 pi bw ts <= 0.5 */

/* ------------------------------------------------------------------ config */

void hd_fw_config_default(hd_fw_config_t *cfg)
{
    memset(cfg, 0, sizeof *cfg);
    /* The project's recommended tuning (filter/hd_kf.h): 0.02 Nm sensor
     * noise, ripple estimates settle in 50 ms, offset in 5 ms. */
    hd_kf_config_recommended(&cfg->kf, HD_FW_TS_S, HD_FW_DEFAULT_NOISE_NM,
                             HD_FW_DEFAULT_RIPPLE_SETTLE_S, HD_FW_DEFAULT_OFFSET_SETTLE_S);
    hd_expected_config_default(&cfg->expected);
    cfg->track_bandwidth_hz = HD_TRACK_DEFAULT_BANDWIDTH_HZ;
    cfg->gear_ratio = 100.0f;
    cfg->motor_cpr = 4096u;
    cfg->output_cpr = 4096u;
    cfg->adc_volts_per_count = 10.0f / 32768.0f;
    cfg->torque_limit_nm = 200.0f;
    cfg->max_motor_speed_rad_s = 1000.0f;
    cfg->telemetry_rate_hz = 1000u;
    cfg->node_id = 1u;
    cfg->filter_enabled = 1u;
}

static bool finite_pos(float x)
{
    return isfinite(x) && x > 0.0f;
}

int hd_fw_config_check(const hd_fw_config_t *cfg)
{
    if (cfg == NULL) {
        return HD_FW_ERR_NULL;
    }
    if (!(cfg->kf.ts_s == HD_FW_TS_S)) {
        return HD_FW_ERR_TS;
    }
    if (hd_kf_config_check(&cfg->kf) != HD_KF_OK) {
        return HD_FW_ERR_KF;
    }
    if (hd_expected_config_check(&cfg->expected) != 0) {
        return HD_FW_ERR_EXPECTED;
    }
    if (!finite_pos(cfg->track_bandwidth_hz) || cfg->track_bandwidth_hz > TRACK_MAX_BANDWIDTH_HZ) {
        return HD_FW_ERR_BANDWIDTH;
    }
    if (!isfinite(cfg->gear_ratio) || cfg->gear_ratio < 1.0f) {
        return HD_FW_ERR_GEAR;
    }
    if (cfg->motor_cpr == 0u || cfg->output_cpr == 0u) {
        return HD_FW_ERR_CPR;
    }
    if (!finite_pos(cfg->adc_volts_per_count)) {
        return HD_FW_ERR_ADC;
    }
    if (!finite_pos(cfg->torque_limit_nm) || !finite_pos(cfg->max_motor_speed_rad_s)) {
        return HD_FW_ERR_LIMIT;
    }
    if (cfg->telemetry_rate_hz > HD_FW_TICK_HZ) {
        return HD_FW_ERR_RATE;
    }
    if (cfg->node_id < HD_CAN_NODE_MIN || cfg->node_id > HD_CAN_NODE_MAX) {
        return HD_FW_ERR_NODE;
    }
    return HD_FW_OK;
}

const char *hd_fw_err_str(int err)
{
    switch (err) {
    case HD_FW_OK: return "ok";
    case HD_FW_ERR_NULL: return "null argument";
    case HD_FW_ERR_KF: return "filter configuration rejected (hd_kf_config_check)";
    case HD_FW_ERR_EXPECTED: return "expected-torque coefficients must be finite and >= 0";
    case HD_FW_ERR_BANDWIDTH: return "track_bandwidth_hz must be in (0, 79]";
    case HD_FW_ERR_GEAR: return "gear_ratio must be >= 1";
    case HD_FW_ERR_CPR: return "encoder counts per rev must be >= 1";
    case HD_FW_ERR_ADC: return "adc_volts_per_count must be > 0";
    case HD_FW_ERR_LIMIT: return "torque_limit_nm and max_motor_speed_rad_s must be > 0";
    case HD_FW_ERR_RATE: return "telemetry_rate_hz must be 0..1000";
    case HD_FW_ERR_NODE: return "node_id must be 1..127";
    case HD_FW_ERR_TS: return "filter sample period must be 1 ms";
    case HD_FW_ERR_HAL: return "the HAL has no sensors";
    default: return "unknown error";
    }
}

/* Derived constants that follow from the configuration. */
static void derive(hd_fw_t *fw)
{
    const hd_fw_config_t *c = &fw->cfg;
    fw->motor_rad_per_count = HD_TWO_PI_F / (float)c->motor_cpr;
    fw->output_rad_per_count = HD_TWO_PI_F / (float)c->output_cpr;
    /* The most counts a healthy encoder can move in one tick, plus 2 counts
     * of quantisation margin; more than that is a glitch. */
    float motor_counts = c->max_motor_speed_rad_s * HD_FW_TS_S / fw->motor_rad_per_count;
    float output_counts = motor_counts / c->gear_ratio * (float)c->output_cpr / (float)c->motor_cpr;
    fw->max_motor_delta_counts = motor_counts > 1.0e9f ? 1000000000 : (int32_t)motor_counts + 2;
    fw->max_output_delta_counts = output_counts > 1.0e9f ? 1000000000 : (int32_t)output_counts + 2;
    if (c->telemetry_rate_hz == 0u) {
        fw->telem_divider = 0u;
    } else {
        fw->telem_divider = (HD_FW_TICK_HZ + c->telemetry_rate_hz / 2u) / c->telemetry_rate_hz;
    }
    if (fw->telem_countdown >= fw->telem_divider) {
        fw->telem_countdown = 0u;
    }
}

/* ------------------------------------------------------------- calibration */

hd_calib_storage_t hd_fw_calib_storage(const hal_t *hal)
{
    hd_calib_storage_t s;
    memset(&s, 0, sizeof s);
    s.ctx = hal->nvm.ctx;
    s.size = hal->nvm.size;
    s.read = hal->nvm.read;
    s.write = hal->nvm.write;
    s.erase = hal->nvm.erase;
    return s;
}

static uint8_t calib_status_code(int load_result)
{
    switch (load_result) {
    case HD_CALIB_LOAD_OK: return 0u;
    case HD_CALIB_LOAD_ONE_COPY_BAD: return 1u;
    case HD_CALIB_LOAD_MISSING: return 2u;
    case HD_CALIB_LOAD_CORRUPT: return 3u;
    case HD_CALIB_LOAD_BAD_VERSION: return 4u;
    default: return 5u;
    }
}

static uint16_t calib_faults_of(int load_result)
{
    if (load_result == HD_CALIB_LOAD_OK) {
        return 0u;
    }
    if (load_result == HD_CALIB_LOAD_ONE_COPY_BAD) {
        return HD_FAULT_CALIB_ONE_COPY;
    }
    if (load_result == HD_CALIB_LOAD_MISSING) {
        return HD_FAULT_CALIB_MISSING;
    }
    return HD_FAULT_CALIB_CORRUPT;
}

/* A record can pass its CRC and still hold nonsense (written by a buggy
 * tool): a gain far outside any bridge/amplifier chain would turn every
 * sample into an overflow.  The bounds are generous (the paper's sensor is
 * 6.6 N m/V). */
static bool calib_gain_plausible(float gain_nm_per_v)
{
    return gain_nm_per_v > 0.0f && gain_nm_per_v <= HD_FW_CALIB_GAIN_MAX_NM_PER_V;
}

static bool calib_offset_plausible(float offset_v)
{
    return offset_v >= -HD_FW_CALIB_OFFSET_MAX_V && offset_v <= HD_FW_CALIB_OFFSET_MAX_V;
}

/* Loads the record; on any failure the defaults are used and the fault flag
 * stays raised until a good record is saved or loaded. */
static int load_calibration(hd_fw_t *fw, hd_calib_record_t *rec, uint32_t *seq)
{
    int rc;
    if (fw->hal->nvm.read == NULL) {
        hd_calib_record_default(rec);
        rc = HD_CALIB_LOAD_MISSING;
    } else {
        hd_calib_storage_t s = hd_fw_calib_storage(fw->hal);
        rc = hd_calib_store_load(&s, rec, seq);
        if ((rc == HD_CALIB_LOAD_OK || rc == HD_CALIB_LOAD_ONE_COPY_BAD) &&
            (!calib_gain_plausible(rec->gain_nm_per_v) ||
             !calib_offset_plausible(rec->offset_v))) {
            rc = HD_CALIB_LOAD_CORRUPT;
        }
        if (rc != HD_CALIB_LOAD_OK && rc != HD_CALIB_LOAD_ONE_COPY_BAD) {
            hd_calib_record_default(rec); /* do not trust whatever was filled in */
        }
    }
    return rc;
}

/* --------------------------------------------------------------------- init */

int hd_fw_init(hd_fw_t *fw, const hal_t *hal, const hd_fw_config_t *cfg)
{
    if (fw == NULL || hal == NULL || cfg == NULL) {
        return HD_FW_ERR_NULL;
    }
    int rc = hd_fw_config_check(cfg);
    if (rc != HD_FW_OK) {
        return rc;
    }
    if (hal->sensors.adc_read == NULL) {
        return HD_FW_ERR_HAL;
    }
    memset(fw, 0, sizeof *fw);
    fw->cfg = *cfg;
    fw->hal = hal;
    if (hd_pipeline_init(&fw->pipe, &cfg->kf, &cfg->expected, cfg->track_bandwidth_hz) != 0) {
        return HD_FW_ERR_KF;
    }
    fw->calib_load_result = load_calibration(fw, &fw->calib, &fw->calib_seq);
    fw->calib_faults = calib_faults_of(fw->calib_load_result);
    fw->state = HD_STATE_INIT;
    derive(fw);
    return HD_FW_OK;
}

/* --------------------------------------------------------------- transmit */

static void send_frame(hd_fw_t *fw, const hal_can_frame_t *f)
{
    const hal_can_t *can = &fw->hal->can;
    if (can->send == NULL) {
        return;
    }
    int rc = can->send(can->ctx, f);
    if (rc == HAL_OK) {
        return;
    }
    /* Dropped: the fault shows in the next frame that gets through. */
    fw->pending_faults |= (rc == HAL_ERR_FAULT) ? HD_FAULT_CAN_BUS_OFF : HD_FAULT_CAN_TX_FULL;
}

static void send_ack(hd_fw_t *fw, uint8_t node, const hd_can_cmd_t *cmd, int result,
                     uint8_t aux, float value)
{
    hd_can_ack_t a = {cmd->opcode, cmd->token, (uint8_t)result, aux, value};
    hal_can_frame_t f;
    hd_can_encode_ack(node, &a, &f);
    send_frame(fw, &f);
    if (result != HD_CAN_RES_OK) {
        fw->counters.command_errors++;
        fw->pending_faults |= HD_FAULT_CMD_ERROR;
    }
}

/* ---------------------------------------------------------------- commands */

/* Builds the pipeline for a new configuration in the scratch slot; swaps it
 * in only if everything accepts it. */
static int apply_config(hd_fw_t *fw, const hd_fw_config_t *next)
{
    if (hd_fw_config_check(next) != HD_FW_OK) {
        return HD_CAN_RES_REJECTED;
    }
    if (hd_pipeline_init(&fw->scratch, &next->kf, &next->expected, next->track_bandwidth_hz) != 0) {
        return HD_CAN_RES_REJECTED;
    }
    fw->pipe = fw->scratch;
    fw->cfg = *next;
    derive(fw);
    return HD_CAN_RES_OK;
}

static bool is_flag_value(float v)
{
    return v == 0.0f || v == 1.0f;
}

static bool is_whole(float v, float lo, float hi)
{
    return v >= lo && v <= hi && v == (float)(int32_t)v;
}

static float param_value(const hd_fw_t *fw, int id)
{
    const hd_fw_config_t *c = &fw->cfg;
    switch (id) {
    case HD_PARAM_R_NM2: return c->kf.r_nm2;
    case HD_PARAM_GEAR_RATIO: return c->gear_ratio;
    case HD_PARAM_INERTIA_KGM2: return c->expected.inertia_kgm2;
    case HD_PARAM_VISCOUS_NM_S_RAD: return c->expected.viscous_nm_s_rad;
    case HD_PARAM_COULOMB_NM: return c->expected.coulomb_nm;
    case HD_PARAM_OFFSET_ENABLED: return (float)c->kf.offset_enabled;
    case HD_PARAM_OFFSET_Q_NM2: return c->kf.offset_q_nm2;
    case HD_PARAM_P0_NM2: return c->kf.p0_nm2;
    case HD_PARAM_TRACK_BANDWIDTH_HZ: return c->track_bandwidth_hz;
    case HD_PARAM_TELEMETRY_RATE_HZ: return (float)c->telemetry_rate_hz;
    case HD_PARAM_NODE_ID: return (float)c->node_id;
    case HD_PARAM_CALIB_GAIN_NM_PER_V: return fw->calib.gain_nm_per_v;
    case HD_PARAM_CALIB_OFFSET_V: return fw->calib.offset_v;
    case HD_PARAM_BLOCK_COUNT: return (float)c->kf.block_count;
    case HD_PARAM_FILTER_ENABLED: return (float)c->filter_enabled;
    default: return 0.0f;
    }
}

/* SET_PARAM.  *new_node is set when the node id changes (after the ACK). */
static int set_param(hd_fw_t *fw, int id, float v, uint8_t *new_node)
{
    hd_fw_config_t next = fw->cfg;
    switch (id) {
    case HD_PARAM_R_NM2:
        if (!(v > 0.0f)) return HD_CAN_RES_OUT_OF_RANGE;
        next.kf.r_nm2 = v;
        return apply_config(fw, &next);
    case HD_PARAM_GEAR_RATIO:
        if (!(v >= 1.0f)) return HD_CAN_RES_OUT_OF_RANGE;
        next.gear_ratio = v;
        return apply_config(fw, &next);
    case HD_PARAM_INERTIA_KGM2:
    case HD_PARAM_VISCOUS_NM_S_RAD:
    case HD_PARAM_COULOMB_NM:
        if (!(v >= 0.0f)) return HD_CAN_RES_OUT_OF_RANGE;
        if (id == HD_PARAM_INERTIA_KGM2) {
            next.expected.inertia_kgm2 = v;
        } else if (id == HD_PARAM_VISCOUS_NM_S_RAD) {
            next.expected.viscous_nm_s_rad = v;
        } else {
            next.expected.coulomb_nm = v;
        }
        return apply_config(fw, &next);
    case HD_PARAM_OFFSET_ENABLED:
        if (!is_flag_value(v)) return HD_CAN_RES_OUT_OF_RANGE;
        next.kf.offset_enabled = (uint8_t)v;
        return apply_config(fw, &next);
    case HD_PARAM_OFFSET_Q_NM2:
    case HD_PARAM_P0_NM2:
        if (!(v >= 0.0f)) return HD_CAN_RES_OUT_OF_RANGE;
        if (id == HD_PARAM_OFFSET_Q_NM2) {
            next.kf.offset_q_nm2 = v;
        } else {
            next.kf.p0_nm2 = v;
        }
        return apply_config(fw, &next);
    case HD_PARAM_TRACK_BANDWIDTH_HZ:
        if (!(v > 0.0f && v <= TRACK_MAX_BANDWIDTH_HZ)) return HD_CAN_RES_OUT_OF_RANGE;
        next.track_bandwidth_hz = v;
        return apply_config(fw, &next);
    case HD_PARAM_TELEMETRY_RATE_HZ:
        if (!is_whole(v, 0.0f, (float)HD_FW_TICK_HZ)) return HD_CAN_RES_OUT_OF_RANGE;
        fw->cfg.telemetry_rate_hz = (uint16_t)v;
        derive(fw);
        return HD_CAN_RES_OK;
    case HD_PARAM_NODE_ID:
        if (!is_whole(v, (float)HD_CAN_NODE_MIN, (float)HD_CAN_NODE_MAX)) {
            return HD_CAN_RES_OUT_OF_RANGE;
        }
        *new_node = (uint8_t)v;
        return HD_CAN_RES_OK;
    case HD_PARAM_CALIB_GAIN_NM_PER_V:
        if (!calib_gain_plausible(v)) return HD_CAN_RES_OUT_OF_RANGE;
        fw->calib.gain_nm_per_v = v;
        return HD_CAN_RES_OK;
    case HD_PARAM_CALIB_OFFSET_V:
        if (!calib_offset_plausible(v)) return HD_CAN_RES_OUT_OF_RANGE;
        fw->calib.offset_v = v;
        return HD_CAN_RES_OK;
    case HD_PARAM_BLOCK_COUNT:
        return HD_CAN_RES_READ_ONLY;
    case HD_PARAM_FILTER_ENABLED:
        if (!is_flag_value(v)) return HD_CAN_RES_OUT_OF_RANGE;
        fw->cfg.filter_enabled = (uint8_t)v;
        return HD_CAN_RES_OK;
    default:
        return HD_CAN_RES_UNKNOWN_PARAM;
    }
}

static int add_block(hd_fw_t *fw, const hd_can_cmd_t *cmd, uint8_t *index)
{
    hd_fw_config_t next = fw->cfg;
    if (!(cmd->order > 0.0f) || !(cmd->value >= 0.0f)) {
        return HD_CAN_RES_OUT_OF_RANGE;
    }
    if (cmd->opcode == HD_CMD_ADD_FIXED && cmd->order >= 0.5f / HD_FW_TS_S) {
        return HD_CAN_RES_OUT_OF_RANGE;
    }
    if (next.kf.block_count >= HD_KF_MAX_BLOCKS) {
        return HD_CAN_RES_NO_SPACE;
    }
    hd_kf_block_config_t *b = &next.kf.blocks[next.kf.block_count];
    b->lock = (uint8_t)(cmd->opcode - HD_CMD_ADD_MOTOR); /* MOTOR, OUTPUT, FIXED in order */
    b->enabled = 1u;
    b->order = cmd->order;
    b->q_nm2 = cmd->value;
    *index = next.kf.block_count;
    next.kf.block_count++;
    return apply_config(fw, &next);
}

static int tare(hd_fw_t *fw, float *offset_v)
{
    if (fw->tare_n == 0u) {
        return HD_CAN_RES_NO_DATA;
    }
    /* Summed afresh (bounded: 64 adds) so no running sum drifts. */
    float sum = 0.0f;
    for (uint32_t i = 0; i < fw->tare_n; i++) {
        sum += fw->tare_v[i];
    }
    fw->calib.offset_v = sum / (float)fw->tare_n;
    *offset_v = fw->calib.offset_v;
    return HD_CAN_RES_OK;
}

void hd_fw_handle_frame(hd_fw_t *fw, const hal_can_frame_t *frame)
{
    const uint8_t node = fw->cfg.node_id;
    if ((frame->flags & HAL_CAN_FLAG_ERR) != 0u || frame->id != HD_CAN_ID_CMD + node) {
        return; /* not addressed to this node */
    }
    fw->counters.commands++;
    hd_can_cmd_t cmd;
    int res = hd_can_decode_cmd(frame, &cmd);
    uint8_t aux = 0u;
    float value = 0.0f;
    uint8_t new_node = 0u;
    if (res == HD_CAN_RES_OK) {
        switch (cmd.opcode) {
        case HD_CMD_FILTER_ENABLE:
            if (cmd.arg_u8[0] > 1u) {
                res = HD_CAN_RES_OUT_OF_RANGE;
            } else {
                fw->cfg.filter_enabled = cmd.arg_u8[0];
            }
            break;
        case HD_CMD_ADD_MOTOR:
        case HD_CMD_ADD_OUTPUT:
        case HD_CMD_ADD_FIXED:
            res = add_block(fw, &cmd, &aux);
            break;
        case HD_CMD_BLOCK_ENABLE:
            aux = cmd.arg_u8[0];
            if (cmd.arg_u8[0] >= fw->cfg.kf.block_count) {
                res = HD_CAN_RES_BAD_INDEX;
            } else if (cmd.arg_u8[1] > 1u) {
                res = HD_CAN_RES_OUT_OF_RANGE;
            } else if (hd_kf_set_block_enabled(&fw->pipe.kf, cmd.arg_u8[0], cmd.arg_u8[1] != 0u) !=
                       HD_KF_OK) {
                res = HD_CAN_RES_REJECTED;
            } else {
                fw->cfg.kf.blocks[cmd.arg_u8[0]].enabled = cmd.arg_u8[1];
            }
            break;
        case HD_CMD_BLOCKS_CLEAR: {
            hd_fw_config_t next = fw->cfg;
            next.kf.block_count = 0u;
            res = apply_config(fw, &next);
            break;
        }
        case HD_CMD_SET_PARAM:
            aux = cmd.arg_u8[0];
            res = set_param(fw, cmd.arg_u8[0], cmd.value, &new_node);
            value = param_value(fw, cmd.arg_u8[0]);
            if (new_node != 0u) {
                value = (float)new_node;
            }
            break;
        case HD_CMD_GET_PARAM:
            aux = cmd.arg_u8[0];
            if (cmd.arg_u8[0] == 0u || cmd.arg_u8[0] >= HD_PARAM_COUNT_) {
                res = HD_CAN_RES_UNKNOWN_PARAM;
            } else {
                value = param_value(fw, cmd.arg_u8[0]);
            }
            break;
        case HD_CMD_TARE:
            res = tare(fw, &value);
            break;
        case HD_CMD_CALIB_SAVE:
        case HD_CMD_CALIB_LOAD:
            if (fw->nvm_pending != 0u) {
                res = HD_CAN_RES_BUSY;
            } else if (fw->hal->nvm.read == NULL || fw->hal->nvm.write == NULL) {
                res = HD_CAN_RES_NVM_ERROR;
            } else {
                /* done by hd_fw_background, which sends the ACK */
                fw->nvm_pending = (cmd.opcode == HD_CMD_CALIB_SAVE) ? 1u : 2u;
                fw->nvm_token = cmd.token;
                fw->nvm_unix_s = cmd.arg_u32;
                return;
            }
            break;
        case HD_CMD_FILTER_RESET:
            hd_kf_reset(&fw->pipe.kf);
            break;
        default:
            res = HD_CAN_RES_UNKNOWN_OPCODE; /* unreachable: the decoder checks */
            break;
        }
    }
    send_ack(fw, node, &cmd, res, aux, value);
    if (res == HD_CAN_RES_OK && new_node != 0u) {
        fw->cfg.node_id = new_node;
    }
}

bool hd_fw_background(hd_fw_t *fw)
{
    if (fw == NULL || fw->nvm_pending == 0u) {
        return false;
    }
    hd_can_cmd_t cmd = {0};
    cmd.token = fw->nvm_token;
    int res = HD_CAN_RES_OK;
    float value = 0.0f;
    uint8_t aux = 0u;
    hd_calib_storage_t s = hd_fw_calib_storage(fw->hal);
    if (fw->nvm_pending == 1u) {
        cmd.opcode = HD_CMD_CALIB_SAVE;
        hd_calib_record_t rec = fw->calib;
        rec.calibrated_unix_s = fw->nvm_unix_s;
        if (hd_calib_store_save(&s, &rec) != 0) {
            res = HD_CAN_RES_NVM_ERROR;
        } else {
            fw->calib = rec;
            fw->calib_load_result = HD_CALIB_LOAD_OK;
            fw->calib_faults = 0u;
        }
    } else {
        cmd.opcode = HD_CMD_CALIB_LOAD;
        hd_calib_record_t rec;
        uint32_t seq = 0u;
        int rc = hd_calib_store_load(&s, &rec, &seq);
        aux = calib_status_code(rc);
        if (rc == HD_CALIB_LOAD_OK || rc == HD_CALIB_LOAD_ONE_COPY_BAD) {
            fw->calib = rec;
            fw->calib_seq = seq;
            fw->calib_load_result = rc;
            fw->calib_faults = calib_faults_of(rc);
            value = rec.gain_nm_per_v;
        } else {
            res = HD_CAN_RES_NVM_ERROR; /* calibration in RAM unchanged */
        }
    }
    fw->nvm_pending = 0u;
    send_ack(fw, fw->cfg.node_id, &cmd, res, aux, value);
    return true;
}

/* ---------------------------------------------------------------- the tick */

static int32_t abs32(int32_t v)
{
    return v < 0 ? (v == INT32_MIN ? INT32_MAX : -v) : v;
}

/* One encoder channel: the wrapped count delta, with glitch rejection. */
static int32_t encoder_delta(uint32_t counts, uint32_t *prev, int32_t *last_good, int32_t max_delta,
                             bool *glitch)
{
    int32_t d = (int32_t)(counts - *prev); /* modulo 2^32: wraps are fine */
    *prev = counts; /* track the raw count so a one-sample spike costs no angle */
    if (abs32(d) > max_delta) {
        *glitch = true;
        return *last_good;
    }
    *last_good = d;
    return d;
}

static uint16_t read_encoders(hd_fw_t *fw, float *d_motor_rad, float *d_output_rad)
{
    const hal_sensors_t *s = &fw->hal->sensors;
    hal_encoder_sample_t enc;
    memset(&enc, 0, sizeof enc);
    int rc = (s->encoder_read != NULL) ? s->encoder_read(s->ctx, &enc) : HAL_ERR_NO_DATA;
    uint16_t faults = 0u;
    int32_t dm;
    int32_t dout;
    if (rc != HAL_OK || enc.fault) {
        /* No usable counts: assume the previous motion continues. */
        faults |= HD_FAULT_ENC_FAULT;
        dm = fw->last_good_motor_delta;
        dout = fw->last_good_output_delta;
        fw->prev_motor_counts += (uint32_t)dm;
        fw->prev_output_counts += (uint32_t)dout;
        enc.has_output = fw->output_present;
    } else if (!fw->have_prev) {
        fw->have_prev = true;
        fw->prev_motor_counts = enc.motor_counts;
        fw->prev_output_counts = enc.output_counts;
        fw->output_present = enc.has_output;
        dm = 0;
        dout = 0;
    } else {
        bool glitch = false;
        fw->output_present = enc.has_output;
        dm = encoder_delta(enc.motor_counts, &fw->prev_motor_counts, &fw->last_good_motor_delta,
                           fw->max_motor_delta_counts, &glitch);
        dout = 0;
        if (enc.has_output) {
            dout = encoder_delta(enc.output_counts, &fw->prev_output_counts,
                                 &fw->last_good_output_delta, fw->max_output_delta_counts, &glitch);
        }
        if (glitch) {
            faults |= HD_FAULT_ENC_GLITCH;
        }
    }
    *d_motor_rad = (float)dm * fw->motor_rad_per_count;
    *d_output_rad = enc.has_output ? (float)dout * fw->output_rad_per_count
                                   : *d_motor_rad / fw->cfg.gear_ratio;
    return faults;
}

static uint16_t read_torque(hd_fw_t *fw, int adc_rc, const hal_adc_sample_t *adc, float *volts,
                            float *torque_nm)
{
    *volts = NAN;
    *torque_nm = NAN;
    if (adc_rc == HAL_ERR_FAULT) {
        return HD_FAULT_OPEN_BRIDGE;
    }
    if (adc_rc != HAL_OK) {
        return HD_FAULT_ADC_ERROR;
    }
    if (adc->saturated) {
        return HD_FAULT_ADC_SATURATED;
    }
    float v = (float)adc->bridge_counts * fw->cfg.adc_volts_per_count;
    float t = fw->calib.gain_nm_per_v * (v - fw->calib.offset_v);
    *volts = v;
    if (!isfinite(t)) {
        return HD_FAULT_ADC_ERROR;
    }
    if (t > fw->cfg.torque_limit_nm || t < -fw->cfg.torque_limit_nm) {
        return HD_FAULT_TORQUE_RANGE;
    }
    *torque_nm = t;
    return 0u;
}

static void check_deadline(hd_fw_t *fw, uint64_t t_us)
{
    if (fw->have_prev_time && t_us - fw->prev_t_us > (uint64_t)HD_FW_TS_US * 3u / 2u) {
        uint64_t missed = (t_us - fw->prev_t_us + HD_FW_TS_US / 2u) / HD_FW_TS_US - 1u;
        hd_fw_note_deadline_miss(fw, missed > 0xFFFFu ? 0xFFFFu : (uint32_t)missed);
    }
    fw->prev_t_us = t_us;
    fw->have_prev_time = true;
}

static void receive_commands(hd_fw_t *fw)
{
    const hal_can_t *can = &fw->hal->can;
    if (can->recv == NULL) {
        return;
    }
    for (unsigned i = 0; i < HD_FW_RX_PER_TICK; i++) {
        hal_can_frame_t f;
        if (can->recv(can->ctx, &f) != HAL_OK) {
            break;
        }
        hd_fw_handle_frame(fw, &f);
    }
}

static uint16_t sat16(uint32_t v)
{
    return v > 0xFFFFu ? 0xFFFFu : (uint16_t)v;
}

static void send_telemetry(hd_fw_t *fw, const hd_fw_sample_t *s)
{
    if (fw->telem_divider == 0u) {
        return;
    }
    if (fw->telem_countdown > 0u) {
        fw->telem_countdown--;
        return;
    }
    fw->telem_countdown = fw->telem_divider - 1u;
    hd_can_telem_t t;
    t.torque_filtered_nm = s->torque_filtered_nm;
    t.torque_raw_nm = s->torque_raw_nm;
    t.ripple_nm = s->ripple_nm;
    t.torque_valid = s->valid;
    t.motor_velocity_rad_s = s->motor_velocity_rad_s;
    t.faults = fw->telem_faults;
    t.kf_status = fw->telem_kf_status;
    t.seq = fw->telem_seq++;
    fw->telem_faults = 0u;
    fw->telem_kf_status = 0u;
    hal_can_frame_t a;
    hal_can_frame_t b;
    hd_can_encode_telem(fw->cfg.node_id, &t, &a, &b);
    send_frame(fw, &a);
    send_frame(fw, &b);
    fw->counters.telemetry_frames++;
}

static void send_heartbeat(hd_fw_t *fw)
{
    if (fw->hb_countdown > 0u) {
        fw->hb_countdown--;
        return;
    }
    fw->hb_countdown = HD_FW_HEARTBEAT_TICKS - 1u;
    hd_can_heartbeat_t h;
    h.state = fw->state;
    h.faults = fw->hb_faults;
    h.deadline_misses = sat16(fw->counters.deadline_misses);
    h.fault_ticks = sat16(fw->counters.fault_ticks);
    h.calib_status = calib_status_code(fw->calib_load_result);
    fw->hb_faults = 0u;
    hal_can_frame_t f;
    hd_can_encode_heartbeat(fw->cfg.node_id, &h, &f);
    send_frame(fw, &f);
}

void hd_fw_isr(hd_fw_t *fw)
{
    if (fw->ended) {
        return;
    }
    const hal_t *hal = fw->hal;
    uint64_t t_us = (hal->clock.time_us != NULL) ? hal->clock.time_us(hal->clock.ctx)
                                                 : (uint64_t)fw->counters.ticks * HD_FW_TS_US;
    check_deadline(fw, t_us);
    receive_commands(fw);

    hal_adc_sample_t adc;
    memset(&adc, 0, sizeof adc);
    int adc_rc = hal->sensors.adc_read(hal->sensors.ctx, &adc);
    if (adc_rc == HAL_ERR_END) {
        fw->ended = true;
        fw->state = HD_STATE_STOPPED;
        fw->hb_countdown = 0u; /* say so at once */
        send_heartbeat(fw);
        return;
    }
    hd_fw_sample_t s;
    memset(&s, 0, sizeof s);
    s.t_us = t_us;
    s.bridge_counts = adc.bridge_counts;
    uint16_t faults = read_torque(fw, adc_rc, &adc, &s.bridge_v, &s.torque_raw_nm);
    s.valid = faults == 0u;
    faults |= read_encoders(fw, &s.d_motor_angle_rad, &s.d_output_angle_rad);

    hd_kf_output_t out;
    hd_pipeline_step(&fw->pipe, s.torque_raw_nm, s.d_motor_angle_rad, s.d_output_angle_rad, 0.0f,
                     &out);
    s.kf_status = out.status;
    s.torque_expected_nm = fw->pipe.torque_expected_nm;
    s.motor_velocity_rad_s = fw->pipe.output_track.vel_rad_s * fw->cfg.gear_ratio;
    if (!s.valid) {
        s.torque_filtered_nm = NAN;
        s.ripple_nm = out.ripple_nm;
    } else if (fw->cfg.filter_enabled) {
        s.torque_filtered_nm = out.torque_filtered_nm;
        s.ripple_nm = out.ripple_nm;
    } else {
        s.torque_filtered_nm = s.torque_raw_nm;
        s.ripple_nm = 0.0f;
    }
    if ((out.status & HD_KF_STATUS_FROZEN) != 0u) {
        faults |= HD_FAULT_KF_FROZEN;
    }
    if ((out.status & HD_KF_STATUS_RESET) != 0u) {
        faults |= HD_FAULT_KF_RESET;
    }
    if (s.valid) {
        fw->counters.valid_samples++;
        fw->tare_v[fw->tare_next] = s.bridge_v;
        fw->tare_next = (fw->tare_next + 1u) % HD_FW_TARE_TICKS;
        if (fw->tare_n < HD_FW_TARE_TICKS) {
            fw->tare_n++;
        }
    }

    faults |= fw->calib_faults | fw->pending_faults;
    fw->pending_faults = 0u;
    s.faults = faults;
    fw->telem_faults |= faults;
    fw->telem_kf_status |= (uint8_t)out.status;
    fw->hb_faults |= faults;
    if (faults != 0u) {
        fw->counters.fault_ticks++;
        for (unsigned bit = 0; bit < HD_FAULT_COUNT; bit++) {
            if ((faults & (1u << bit)) != 0u) {
                fw->counters.by_fault[bit]++;
            }
        }
    }
    fw->state = (fw->hb_faults != 0u) ? HD_STATE_DEGRADED : HD_STATE_RUN;
    fw->last = s;
    fw->counters.ticks++;

    send_telemetry(fw, &s);
    send_heartbeat(fw);
}

void hd_fw_note_deadline_miss(hd_fw_t *fw, uint32_t missed_ticks)
{
    if (missed_ticks == 0u) {
        return;
    }
    fw->counters.deadline_misses += missed_ticks;
    fw->pending_faults |= HD_FAULT_DEADLINE_MISS;
}

const hd_fw_sample_t *hd_fw_last_sample(const hd_fw_t *fw)
{
    return &fw->last;
}

const hd_fw_counters_t *hd_fw_counters(const hd_fw_t *fw)
{
    return &fw->counters;
}
