/* hd_fw_records: the configuration record's codec, and the firmware's
 * record jobs (boot, CALIB_SAVE/LOAD, CONFIG_SAVE/LOAD), which run in the
 * background context.  See hd_fw_records.h and docs/reference/records.md. */
#include "hd_fw_records.h"

#include <math.h> /* sqrtf: an instruction with -fno-math-errno */
#include <string.h>

#include "hd_fw_internal.h"
#include "hd_params.h"

/* ------------------------------------------------- configuration record */

size_t hd_config_record_encode(const hd_fw_config_t *cfg, uint8_t *buf, size_t cap)
{
    size_t n = 0;
    size_t at = 1u;
    for (size_t i = 0; i < hd_param_count(); i++) {
        const hd_param_info_t *p = hd_param_at(i);
        if ((p->flags & HD_PF_CONFIG) == 0u) {
            continue;
        }
        if (at + 5u > cap) {
            return 0u;
        }
        buf[at] = p->id;
        hd_le_put_f32(buf + at + 1u, hd_param_get(p, cfg));
        at += 5u;
        n++;
    }
    if (cap < 1u || at + 1u + 10u * cfg->kf.block_count > cap) {
        return 0u;
    }
    buf[0] = (uint8_t)n;
    buf[at++] = cfg->kf.block_count;
    for (unsigned b = 0; b < cfg->kf.block_count; b++) {
        const hd_kf_block_config_t *blk = &cfg->kf.blocks[b];
        buf[at] = blk->lock;
        buf[at + 1u] = blk->enabled;
        hd_le_put_f32(buf + at + 2u, blk->order);
        hd_le_put_f32(buf + at + 6u, blk->q_nm2);
        at += 10u;
    }
    return at;
}

hd_record_status_t hd_config_record_decode(const uint8_t *buf, size_t len,
                                           const hd_fw_config_t *base, hd_fw_config_t *out)
{
    if (buf == NULL || base == NULL || out == NULL || len < 2u) {
        return HD_RECORD_CORRUPT;
    }
    hd_fw_config_t c = *base;
    size_t at = 1u;
    for (unsigned i = 0; i < buf[0]; i++) {
        if (at + 5u > len) {
            return HD_RECORD_CORRUPT;
        }
        const hd_param_info_t *p = hd_param_by_id(buf[at]);
        if (p == NULL && hd_param_is_retired(buf[at])) {
            at += 5u; /* saved by an older firmware: the rest still holds */
            continue;
        }
        if (p == NULL) {
            return HD_RECORD_BAD_VERSION; /* written by a newer firmware */
        }
        if ((p->flags & HD_PF_CONFIG) == 0u ||
            hd_param_set(p, &c, hd_le_get_f32(buf + at + 1u)) != HD_FW_OK) {
            return HD_RECORD_CORRUPT;
        }
        at += 5u;
    }
    if (at >= len || buf[at] > HD_KF_MAX_BLOCKS || len != at + 1u + 10u * buf[at]) {
        return HD_RECORD_CORRUPT;
    }
    c.kf.block_count = buf[at++];
    for (unsigned b = 0; b < c.kf.block_count; b++) {
        hd_kf_block_config_t *blk = &c.kf.blocks[b];
        blk->lock = buf[at];
        blk->enabled = buf[at + 1u];
        blk->order = hd_le_get_f32(buf + at + 2u);
        blk->q_nm2 = hd_le_get_f32(buf + at + 6u);
        if (blk->enabled > 1u) {
            return HD_RECORD_CORRUPT;
        }
        at += 10u;
    }
    if (hd_fw_config_check(&c, NULL) != HD_FW_OK) {
        return HD_RECORD_CORRUPT;
    }
    *out = c;
    return HD_RECORD_OK;
}

/* ------------------------------------------------------- profile record */

size_t hd_profile_record_encode(const hd_profile_record_t *r, uint8_t *buf, size_t cap)
{
    const unsigned n = r->profile.line_count;
    const size_t len = HD_PROFILE_RECORD_HEADER + HD_PROFILE_RECORD_LINE * (size_t)n;
    if (n > HD_KF_MAX_BLOCKS || len > cap) {
        return 0u;
    }
    hd_le_put_f32(buf, r->gear_ratio);
    hd_le_put_u32(buf + 4u, r->motor_cpr);
    hd_le_put_u32(buf + 8u, r->output_cpr);
    hd_le_put_f32(buf + 12u, r->profile.load_nm);
    buf[16] = (uint8_t)n;
    uint8_t *at = buf + HD_PROFILE_RECORD_HEADER;
    for (unsigned i = 0; i < n; i++, at += HD_PROFILE_RECORD_LINE) {
        const hd_kf_profile_line_t *l = &r->profile.lines[i];
        at[0] = l->lock;
        at[1] = l->order;
        hd_le_put_f32(at + 2u, l->a_nm);
        hd_le_put_f32(at + 6u, l->b_nm);
    }
    return len;
}

static bool finite_f32(float v)
{
    return (v - v) == 0.0f;
}

hd_record_status_t hd_profile_record_decode(const uint8_t *buf, size_t len, uint16_t version,
                                            hd_profile_record_t *out)
{
    if (version != HD_PROFILE_RECORD_VERSION && version != HD_PROFILE_RECORD_VERSION_V1) {
        return HD_RECORD_BAD_VERSION;
    }
    const bool v1 = version == HD_PROFILE_RECORD_VERSION_V1;
    const size_t header = v1 ? HD_PROFILE_RECORD_HEADER_V1 : HD_PROFILE_RECORD_HEADER;
    if (buf == NULL || out == NULL || len < header) {
        return HD_RECORD_CORRUPT;
    }
    hd_profile_record_t r;
    memset(&r, 0, sizeof r);
    r.gear_ratio = hd_le_get_f32(buf);
    r.motor_cpr = hd_le_get_u32(buf + 4u);
    r.output_cpr = hd_le_get_u32(buf + 8u);
    r.profile.load_nm = v1 ? -1.0f : hd_le_get_f32(buf + 12u);
    const unsigned n = buf[header - 1u];
    if (n > HD_KF_MAX_BLOCKS || len != header + HD_PROFILE_RECORD_LINE * n ||
        !finite_f32(r.gear_ratio) || !(r.gear_ratio >= 1.0f) || r.motor_cpr == 0u ||
        r.output_cpr == 0u || !finite_f32(r.profile.load_nm) ||
        r.profile.load_nm > HD_KF_MAX_ABS_Y_NM) {
        return HD_RECORD_CORRUPT;
    }
    const uint8_t *at = buf + header;
    for (unsigned i = 0; i < n; i++, at += HD_PROFILE_RECORD_LINE) {
        hd_kf_profile_line_t *l = &r.profile.lines[i];
        l->lock = at[0];
        l->order = at[1];
        l->a_nm = hd_le_get_f32(at + 2u);
        l->b_nm = hd_le_get_f32(at + 6u);
        if ((l->lock != HD_KF_LOCK_MOTOR && l->lock != HD_KF_LOCK_OUTPUT) || l->order == 0u ||
            !finite_f32(l->a_nm) || !finite_f32(l->b_nm)) {
            return HD_RECORD_CORRUPT;
        }
    }
    r.profile.line_count = (uint8_t)n;
    *out = r;
    return HD_RECORD_OK;
}

/* ------------------------------------------------------------ statuses */

static bool usable(hd_record_status_t st)
{
    return st == HD_RECORD_OK || st == HD_RECORD_ONE_COPY_BAD;
}

static uint32_t calib_faults_of(hd_record_status_t st)
{
    switch (st) {
    case HD_RECORD_OK: return 0u;
    case HD_RECORD_ONE_COPY_BAD: return HD_FAULT_CALIB_ONE_COPY;
    case HD_RECORD_MISSING: return HD_FAULT_CALIB_MISSING;
    default: return HD_FAULT_CALIB_CORRUPT;
    }
}

/* A missing configuration is the factory state, not a fault; one that
 * exists but cannot be used is. */
static uint32_t config_faults_of(hd_record_status_t st)
{
    return (usable(st) || st == HD_RECORD_MISSING) ? 0u : HD_FAULT_CONFIG_DEFAULTS;
}

#define RECORD_FAULTS_CALIB (HD_FAULT_CALIB_MISSING | HD_FAULT_CALIB_CORRUPT | HD_FAULT_CALIB_ONE_COPY)

/* A record can pass its CRC and still hold nonsense (written by a buggy
 * tool): the table's bounds decide. */
static bool calib_plausible(const hd_calib_record_t *r)
{
    return hd_param_check(hd_param_by_id(HD_PARAM_CALIB_GAIN_NM_PER_V), r->gain_nm_per_v) ==
               HD_FW_OK &&
           hd_param_check(hd_param_by_id(HD_PARAM_CALIB_OFFSET_V), r->offset_v) == HD_FW_OK;
}

static hd_record_status_t load_calib(const hd_fw_t *fw, hd_calib_record_t *rec)
{
    hd_store_io_t io = hd_fw_store_io(fw->hal, NULL, 0u);
    hd_record_status_t st = hd_calib_store_load(&io, rec, NULL);
    if (usable(st) && !calib_plausible(rec)) {
        st = HD_RECORD_CORRUPT;
        hd_calib_record_default(rec); /* do not trust whatever was filled in */
    }
    return st;
}

static hd_record_status_t load_config(hd_fw_t *fw, const hd_fw_config_t *base, hd_fw_config_t *out)
{
    hd_store_io_t io = hd_fw_store_io(fw->hal, NULL, 0u);
    uint8_t buf[HD_CONFIG_RECORD_MAX];
    size_t len = 0u;
    hd_record_status_t st = hd_store_load(&io, HD_RECORD_KIND_CONFIG, HD_CONFIG_RECORD_VERSION,
                                          buf, sizeof buf, &len, NULL, NULL);
    if (!usable(st)) {
        return st;
    }
    hd_record_status_t dec = hd_config_record_decode(buf, len, base, out);
    return dec == HD_RECORD_OK ? st : dec;
}

static void set_calib(hd_fw_settings_t *s, const hd_calib_record_t *rec, hd_record_status_t st)
{
    s->cfg.calib_gain_nm_per_v = rec->gain_nm_per_v;
    s->cfg.calib_offset_v = rec->offset_v;
    s->calib_status = (uint8_t)st;
    s->record_faults = (s->record_faults & ~(uint32_t)RECORD_FAULTS_CALIB) | calib_faults_of(st);
}

/* A profile is only meaningful on the joint it was made on (the same gear
 * ratio and encoder resolutions: the angles would not line up), and a
 * line beyond the torque limit is not a ripple a sensor can have. */
static hd_record_status_t profile_fits(const hd_fw_config_t *c, const hd_profile_record_t *r)
{
    const float d = r->gear_ratio - c->gear_ratio;
    if (d > 1.0e-6f * c->gear_ratio || -d > 1.0e-6f * c->gear_ratio ||
        r->motor_cpr != c->motor_cpr || r->output_cpr != c->output_cpr) {
        return HD_RECORD_REFUSED;
    }
    const float lim2 = c->torque_limit_nm * c->torque_limit_nm;
    float peak_nm = 0.0f;
    for (unsigned i = 0; i < r->profile.line_count; i++) {
        const hd_kf_profile_line_t *l = &r->profile.lines[i];
        const float a2 = l->a_nm * l->a_nm + l->b_nm * l->b_nm;
        if (a2 > lim2) {
            return HD_RECORD_CORRUPT;
        }
        peak_nm += sqrtf(a2); /* background only: VSQRT on the M4F */
    }
    /* lines whose peak sum is beyond the correction envelope would hold the
     * correction at its limit: not this joint's */
    const float env = c->kf.correction_max_nm;
    if (env > 0.0f && peak_nm > env) {
        return HD_RECORD_REFUSED;
    }
    return HD_RECORD_OK;
}

static hd_record_status_t load_profile(const hd_fw_t *fw, const hd_fw_config_t *c,
                                       hd_kf_profile_t *out)
{
    hd_store_io_t io = hd_fw_store_io(fw->hal, NULL, 0u);
    uint8_t buf[HD_PROFILE_RECORD_MAX];
    size_t len = 0u;
    uint16_t version = HD_PROFILE_RECORD_VERSION;
    hd_record_status_t st = hd_store_load(&io, HD_RECORD_KIND_PROFILE, version, buf, sizeof buf,
                                          &len, NULL, &version);
    if (st == HD_RECORD_BAD_VERSION && version == HD_PROFILE_RECORD_VERSION_V1) {
        st = hd_store_load(&io, HD_RECORD_KIND_PROFILE, version, buf, sizeof buf, &len, NULL,
                           NULL); /* saved before the profile kept its load */
    }
    if (!usable(st)) {
        return st;
    }
    hd_profile_record_t r;
    hd_record_status_t dec = hd_profile_record_decode(buf, len, version, &r);
    if (dec == HD_RECORD_OK) {
        dec = profile_fits(c, &r);
    }
    if (dec != HD_RECORD_OK) {
        return dec;
    }
    *out = r.profile;
    return st;
}

/* A missing profile is the factory state (the filter starts from zero, as
 * always); one that exists but cannot be used is a fault. */
static void set_profile_status(hd_fw_settings_t *s, hd_record_status_t st)
{
    s->profile_status = (uint8_t)st;
    s->record_faults &= ~(uint32_t)HD_FAULT_PROFILE_UNUSABLE;
    if (!usable(st) && st != HD_RECORD_MISSING) {
        s->record_faults |= HD_FAULT_PROFILE_UNUSABLE;
    }
}

/* ------------------------------------------------------------------- boot */

void hd_fw_records_boot(hd_fw_t *fw, const hd_fw_config_t *defaults, hd_fw_settings_t *s)
{
    memset(s, 0, sizeof *s);
    hd_record_status_t cst = load_config(fw, defaults, &s->cfg);
    if (!usable(cst)) {
        s->cfg = *defaults;
    }
    fw->bg.config_from_record = usable(cst);
    s->config_status = (uint8_t)cst;
    s->record_faults |= config_faults_of(cst);

    hd_record_status_t kst = load_calib(fw, &fw->bg.calib);
    set_calib(s, &fw->bg.calib, kst);

    memset(&fw->bg.profile, 0, sizeof fw->bg.profile);
    hd_record_status_t pst = load_profile(fw, &s->cfg, &fw->bg.profile);
    set_profile_status(s, pst);
}

/* --------------------------------------------------------- calibration */

int hd_fw_calib_save(hd_fw_t *fw, uint32_t unix_s, hd_fw_settings_t *next)
{
    hd_store_io_t io = hd_fw_store_io(fw->hal, fw->bg.work, sizeof fw->bg.work);
    if (io.write == NULL || io.erase == NULL) {
        return HD_CAN_RES_NVM_ERROR;
    }
    hd_calib_record_t rec = fw->bg.calib;
    rec.gain_nm_per_v = next->cfg.calib_gain_nm_per_v;
    rec.offset_v = next->cfg.calib_offset_v;
    rec.calibrated_unix_s = unix_s;
    if (hd_calib_store_save(&io, &rec) != HD_RECORD_OK) {
        return HD_CAN_RES_NVM_ERROR; /* the stored record is unchanged */
    }
    fw->bg.calib = rec;
    set_calib(next, &rec, HD_RECORD_OK);
    return HD_CAN_RES_OK;
}

int hd_fw_calib_load(hd_fw_t *fw, hd_fw_settings_t *next, uint8_t *aux, float *value)
{
    hd_calib_record_t rec;
    hd_record_status_t st = load_calib(fw, &rec);
    *aux = (uint8_t)st;
    if (!usable(st)) {
        return HD_CAN_RES_NVM_ERROR; /* the calibration in RAM is unchanged */
    }
    fw->bg.calib = rec;
    set_calib(next, &rec, st);
    *value = rec.gain_nm_per_v;
    return HD_CAN_RES_OK;
}

/* ------------------------------------------------------- configuration */

int hd_fw_config_save(hd_fw_t *fw, uint8_t *aux)
{
    hd_store_io_t io = hd_fw_store_io(fw->hal, fw->bg.work, sizeof fw->bg.work);
    if (io.write == NULL || io.erase == NULL) {
        return HD_CAN_RES_NVM_ERROR;
    }
    uint8_t buf[HD_CONFIG_RECORD_MAX];
    size_t len = hd_config_record_encode(&hd_fw_live(fw)->cfg, buf, sizeof buf);
    hd_record_status_t st = (len == 0u) ? HD_RECORD_IO
                                        : hd_store_save(&io, HD_RECORD_KIND_CONFIG,
                                                        HD_CONFIG_RECORD_VERSION, buf, len);
    *aux = (uint8_t)st;
    return st == HD_RECORD_OK ? HD_CAN_RES_OK : HD_CAN_RES_NVM_ERROR;
}

int hd_fw_config_load(hd_fw_t *fw, hd_fw_config_t *next, uint8_t *aux)
{
    hd_record_status_t st = load_config(fw, &fw->bg.defaults, next);
    *aux = (uint8_t)st;
    if (st == HD_RECORD_MISSING) {
        return HD_CAN_RES_NO_DATA;
    }
    return usable(st) ? HD_CAN_RES_OK : HD_CAN_RES_NVM_ERROR;
}

/* ------------------------------------------------------------- profile */

int hd_fw_profile_save(hd_fw_t *fw, const hd_kf_profile_t *lines, hd_fw_settings_t *next,
                       uint8_t *aux)
{
    hd_store_io_t io = hd_fw_store_io(fw->hal, fw->bg.work, sizeof fw->bg.work);
    if (io.write == NULL || io.erase == NULL) {
        *aux = (uint8_t)HD_RECORD_IO;
        return HD_CAN_RES_NVM_ERROR;
    }
    const hd_fw_config_t *c = &next->cfg;
    hd_profile_record_t r = {c->gear_ratio, c->motor_cpr, c->output_cpr, *lines};
    uint8_t buf[HD_PROFILE_RECORD_MAX];
    size_t len = hd_profile_record_encode(&r, buf, sizeof buf);
    hd_record_status_t st = (len == 0u || profile_fits(c, &r) != HD_RECORD_OK)
                                ? HD_RECORD_CORRUPT
                                : hd_store_save(&io, HD_RECORD_KIND_PROFILE,
                                                HD_PROFILE_RECORD_VERSION, buf, len);
    *aux = (uint8_t)st;
    if (st == HD_RECORD_CORRUPT) {
        return HD_CAN_RES_REJECTED; /* a line beyond the torque limit */
    }
    if (st != HD_RECORD_OK) {
        return HD_CAN_RES_NVM_ERROR; /* the stored record is unchanged */
    }
    fw->bg.profile = *lines;
    set_profile_status(next, HD_RECORD_OK);
    return HD_CAN_RES_OK;
}

int hd_fw_profile_load(hd_fw_t *fw, hd_fw_settings_t *next, uint8_t *aux)
{
    hd_kf_profile_t p;
    memset(&p, 0, sizeof p);
    hd_record_status_t st = load_profile(fw, &next->cfg, &p);
    *aux = (uint8_t)st;
    if (st == HD_RECORD_MISSING) {
        return HD_CAN_RES_NO_DATA;
    }
    if (st == HD_RECORD_REFUSED) {
        return HD_CAN_RES_REJECTED;
    }
    if (!usable(st)) {
        return HD_CAN_RES_NVM_ERROR; /* the profile in RAM and the filter are unchanged */
    }
    fw->bg.profile = p;
    set_profile_status(next, st);
    return HD_CAN_RES_OK;
}

int hd_fw_profile_clear(hd_fw_t *fw, hd_fw_settings_t *next, uint8_t *aux)
{
    hd_store_io_t io = hd_fw_store_io(fw->hal, fw->bg.work, sizeof fw->bg.work);
    if (io.write == NULL || io.erase == NULL) {
        *aux = (uint8_t)HD_RECORD_IO;
        return HD_CAN_RES_NVM_ERROR;
    }
    hd_record_status_t st = hd_store_save(&io, HD_RECORD_KIND_PROFILE,
                                          HD_PROFILE_RECORD_VERSION, NULL, 0u);
    *aux = (uint8_t)st;
    if (st != HD_RECORD_OK) {
        return HD_CAN_RES_NVM_ERROR;
    }
    memset(&fw->bg.profile, 0, sizeof fw->bg.profile);
    set_profile_status(next, HD_RECORD_MISSING);
    return HD_CAN_RES_OK;
}
