/* hd_fw_config: see hd_fw_config.h. */
#include "hd_fw_config.h"

#include <math.h> /* isnan, NAN: compiler builtins, no libm call */
#include <string.h>

#include "hd_calib_record.h"
#include "hd_params.h"
#include "hd_track.h"

void hd_fw_ctrl_config(const hd_fw_config_t *cfg, hd_ctrl_config_t *out)
{
    *out = cfg->ctrl;
    out->ts_s = HD_FW_TS_S;
    out->gear_ratio = cfg->gear_ratio;
    /* the narrowed feedback's lines: the filter's motor-locked blocks */
    out->artifact_mask = 0u;
    for (unsigned i = 0; i < cfg->kf.block_count && i < HD_KF_MAX_BLOCKS; i++) {
        const hd_kf_block_config_t *b = &cfg->kf.blocks[i];
        const float k = b->order;
        if (b->enabled != 0u && b->lock == (uint8_t)HD_KF_LOCK_MOTOR && k >= 1.0f &&
            k <= (float)HD_ARTIFACT_ORDER_MAX && k == (float)(unsigned)k) {
            out->artifact_mask |= (uint8_t)(1u << ((unsigned)k - 1u));
        }
    }
}

void hd_fw_config_default(hd_fw_config_t *cfg)
{
    memset(cfg, 0, sizeof *cfg);
    /* the libraries' defaults: the LIB rows */
    hd_kf_config_recommended(&cfg->kf, HD_FW_TS_S, HD_FW_DEFAULT_NOISE_NM,
                             HD_FW_DEFAULT_RIPPLE_SETTLE_S, HD_FW_DEFAULT_OFFSET_SETTLE_S);
    hd_expected_config_default(&cfg->expected);
    cfg->track_bandwidth_hz = HD_TRACK_DEFAULT_BANDWIDTH_HZ;
    cfg->calib_gain_nm_per_v = HD_CALIB_NOMINAL_GAIN_NM_PER_V;
    hd_ctrl_config_default(&cfg->ctrl); /* control/'s defaults */
    /* every other row's default column (in range: fw_config_text checks) */
    for (size_t i = 0; i < hd_param_count(); i++) {
        const hd_param_info_t *p = hd_param_at(i);
        if (!isnan(p->dflt)) {
            (void)hd_param_set(p, cfg, p->dflt);
        }
    }
}

void hd_fw_kf_config(const hd_fw_config_t *cfg, hd_kf_config_t *out)
{
    *out = cfg->kf;
    out->output_learn_scale = (cfg->learning_mode == HD_FW_LEARN_OPERATING)
                                  ? cfg->operating_output_learn_scale
                                  : 1.0f;
    /* the profile's lines held against slow motion only in operation (the
     * learning modes learn them) */
    out->q_motion_ref_profiled_rad = (cfg->learning_mode == HD_FW_LEARN_OPERATING)
                                         ? cfg->kf.q_motion_ref_profiled_rad
                                         : 0.0f;
    if (cfg->learning_mode == HD_FW_LEARN_COMMISSIONING) {
        /* slowed for a known load; at its own rate again for a while after
         * each step beyond the jump gate (the load is not the known one:
         * an operating log, not a bench run; docs/design/filter.md, "Offset drift") */
        out->offset_q_nm2 = cfg->kf.offset_q_nm2 * HD_FW_COMMISSIONING_OFFSET_Q_SCALE;
        out->offset_drift_q_nm2 = cfg->kf.offset_q_nm2;
    }
}

hd_fw_err_t hd_fw_config_check(const hd_fw_config_t *cfg, unsigned *bad_param)
{
    if (bad_param != NULL) {
        *bad_param = 0u;
    }
    if (cfg == NULL) {
        return HD_FW_ERR_NULL;
    }
    if (!(cfg->kf.ts_s == HD_FW_TS_S)) {
        return HD_FW_ERR_TS;
    }
    for (size_t i = 0; i < hd_param_count(); i++) {
        const hd_param_info_t *p = hd_param_at(i);
        if (hd_param_check(p, hd_param_get(p, cfg)) != HD_FW_OK) {
            if (bad_param != NULL) {
                *bad_param = p->id;
            }
            return HD_FW_ERR_RANGE;
        }
    }
    hd_kf_config_t kf;
    hd_fw_kf_config(cfg, &kf);
    if (hd_kf_config_check(&kf) != HD_KF_OK) {
        return HD_FW_ERR_KF;
    }
    if (hd_expected_config_check(&cfg->expected) != 0 ||
        hd_expected_current_check(&cfg->current) != HD_KF_OK) {
        return HD_FW_ERR_EXPECTED;
    }
    /* a line may grow at most HD_FW_MAX_LOAD_GROWTH-fold up to the torque
     * limit: beyond, the coefficient is not a gear's */
    if (cfg->kf.ripple_load_coeff_per_nm * cfg->torque_limit_nm > HD_FW_MAX_LOAD_GROWTH) {
        return HD_FW_ERR_KF;
    }
    hd_ctrl_config_t ctrl;
    hd_fw_ctrl_config(cfg, &ctrl);
    if (hd_ctrl_config_check(&ctrl) != HD_CTRL_OK) {
        return HD_FW_ERR_CONTROL;
    }
    return HD_FW_OK;
}

const char *hd_fw_err_str(int err)
{
    switch (err) {
    case HD_FW_OK: return "ok";
    case HD_FW_ERR_NULL: return "null argument";
    case HD_FW_ERR_KF: return "filter configuration rejected (hd_kf_config_check, or "
                              "ripple_load_coeff_per_nm x torque_limit_nm above 100)";
    case HD_FW_ERR_EXPECTED: return "expected-torque configuration rejected";
    case HD_FW_ERR_RANGE: return "a parameter is outside its range (hd_params.def)";
    case HD_FW_ERR_TS: return "filter sample period must be 1 ms";
    case HD_FW_ERR_HAL: return "the HAL has no sensors";
    case HD_FW_ERR_UNKNOWN_PARAM: return "unknown parameter";
    case HD_FW_ERR_READ_ONLY: return "read-only parameter";
    case HD_FW_ERR_NOT_FINITE: return "value is not a finite number";
    case HD_FW_ERR_NOT_WHOLE: return "value must be a whole number";
    case HD_FW_ERR_SYNTAX: return "line cannot be read";
    case HD_FW_ERR_TOO_MANY_BLOCKS: return "too many filter blocks";
    case HD_FW_ERR_DUPLICATE: return "key given twice";
    case HD_FW_ERR_BYTES: return "NUL, control or non-ASCII byte outside a comment";
    case HD_FW_ERR_TOO_LONG: return "configuration text too long";
    case HD_FW_ERR_CONTROL: return "controller settings rejected (hd_ctrl_config_check)";
    default: return "unknown error";
    }
}
