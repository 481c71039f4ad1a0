/* hd_config_text: see hd_config_text.h and docs/firmware.md. */
#include "hd_config_text.h"

#include <math.h> /* isfinite (builtin) */
#include <string.h>

typedef struct {
    const char *s; /* token start */
    size_t n;      /* token length */
} tok_t;

static bool is_space(char c)
{
    return c == ' ' || c == '\t' || c == '\r';
}

static bool is_digit(char c)
{
    return c >= '0' && c <= '9';
}

/* Appends a decimal digit to the mantissa while fewer than 19 significant
 * digits are kept; returns false when the digit is dropped. */
static bool take_digit(char c, uint64_t *mant, int *digits)
{
    if (*digits >= 19) {
        return false;
    }
    *mant = *mant * 10u + (uint64_t)(c - '0');
    if (*mant != 0u) {
        (*digits)++;
    }
    return true;
}

int hd_config_parse_float(const char *s, size_t n, float *out)
{
    size_t i = 0;
    bool neg = false;
    if (i < n && (s[i] == '+' || s[i] == '-')) {
        neg = s[i] == '-';
        i++;
    }
    /* Up to 19 significant digits in an integer mantissa; later digits only
     * move the decimal exponent.  Exact enough for float32 results. */
    uint64_t mant = 0;
    int digits = 0;
    int dec_exp = 0;
    bool any = false;
    while (i < n && is_digit(s[i])) {
        any = true;
        if (!take_digit(s[i], &mant, &digits)) {
            dec_exp++; /* integer digit past the 19 kept: only the scale */
        }
        i++;
    }
    if (i < n && s[i] == '.') {
        i++;
        while (i < n && is_digit(s[i])) {
            any = true;
            if (take_digit(s[i], &mant, &digits)) {
                dec_exp--; /* a kept fraction digit */
            }
            i++;
        }
    }
    if (!any) {
        return -1;
    }
    if (i < n && (s[i] == 'e' || s[i] == 'E')) {
        i++;
        bool eneg = false;
        if (i < n && (s[i] == '+' || s[i] == '-')) {
            eneg = s[i] == '-';
            i++;
        }
        if (i >= n || !is_digit(s[i])) {
            return -1;
        }
        int e = 0;
        while (i < n && is_digit(s[i])) {
            if (e < 1000) {
                e = e * 10 + (s[i] - '0');
            }
            i++;
        }
        dec_exp += eneg ? -e : e;
    }
    if (i != n) {
        return -1;
    }
    double v = (double)mant;
    if (mant != 0u) {
        if (dec_exp > 60 || dec_exp < -80) {
            /* far outside float range either way: reject rather than
             * silently turn into 0 or infinity */
            return -1;
        }
        double p = 1.0;
        int e = dec_exp < 0 ? -dec_exp : dec_exp;
        for (int k = 0; k < e; k++) {
            p *= 10.0;
        }
        v = dec_exp < 0 ? v / p : v * p;
    }
    float f = (float)(neg ? -v : v);
    if (!isfinite(f) || (mant != 0u && f == 0.0f)) {
        return -1;
    }
    *out = f;
    return 0;
}

static int parse_uint(tok_t t, uint32_t max, uint32_t *out)
{
    if (t.n == 0u || t.n > 10u) {
        return -1;
    }
    uint64_t v = 0;
    for (size_t i = 0; i < t.n; i++) {
        if (!is_digit(t.s[i])) {
            return -1;
        }
        v = v * 10u + (uint64_t)(t.s[i] - '0');
    }
    if (v > max) {
        return -2;
    }
    *out = (uint32_t)v;
    return 0;
}

static bool tok_eq(tok_t t, const char *lit)
{
    size_t n = strlen(lit);
    return t.n == n && memcmp(t.s, lit, n) == 0;
}

/* Splits [s, s+n) into whitespace-separated tokens; returns the count, or
 * max+1 if there are more than max. */
static size_t split(const char *s, size_t n, tok_t *toks, size_t max)
{
    size_t count = 0;
    size_t i = 0;
    while (i < n) {
        while (i < n && is_space(s[i])) {
            i++;
        }
        if (i >= n) {
            break;
        }
        size_t start = i;
        while (i < n && !is_space(s[i])) {
            i++;
        }
        if (count == max) {
            return max + 1u;
        }
        toks[count].s = s + start;
        toks[count].n = i - start;
        count++;
    }
    return count;
}

typedef enum { V_POS, V_NONNEG, V_ANY } float_rule_t;

typedef struct {
    const char *key;
    float_rule_t rule;
    size_t offset; /* of the float inside hd_fw_config_t */
} float_key_t;

#define FKEY(name, rule, field) {name, rule, offsetof(hd_fw_config_t, field)}
static const float_key_t FLOAT_KEYS[] = {
    FKEY("gear_ratio", V_POS, gear_ratio),
    FKEY("r_nm2", V_POS, kf.r_nm2),
    FKEY("p0_nm2", V_NONNEG, kf.p0_nm2),
    FKEY("p_max_nm2", V_POS, kf.p_max_nm2),
    FKEY("nyquist_fraction", V_POS, kf.nyquist_fraction),
    FKEY("offset_q_nm2", V_NONNEG, kf.offset_q_nm2),
    FKEY("output_p0_nm2", V_NONNEG, kf.output_p0_nm2),
    FKEY("offset_jump_nm", V_NONNEG, kf.offset_jump_nm),
    FKEY("q_motion_ref_rad", V_NONNEG, kf.q_motion_ref_rad),
    FKEY("ripple_load_coeff_per_nm", V_NONNEG, kf.ripple_load_coeff_per_nm),
    FKEY("inertia_kgm2", V_NONNEG, expected.inertia_kgm2),
    FKEY("viscous_nm_s_rad", V_NONNEG, expected.viscous_nm_s_rad),
    FKEY("coulomb_nm", V_NONNEG, expected.coulomb_nm),
    FKEY("coulomb_vel_eps_rad_s", V_POS, expected.coulomb_vel_eps_rad_s),
    FKEY("track_bandwidth_hz", V_POS, track_bandwidth_hz),
    FKEY("adc_volts_per_count", V_POS, adc_volts_per_count),
    FKEY("torque_limit_nm", V_POS, torque_limit_nm),
    FKEY("max_motor_speed_rad_s", V_POS, max_motor_speed_rad_s),
};

static int fail(hd_cfgtxt_error_t *err, int code, unsigned line, const char *msg)
{
    if (err != NULL) {
        err->code = code;
        err->line = line;
        err->message = msg;
        err->fw_err = 0;
    }
    return code;
}

static int parse_on_off(tok_t t, uint8_t *out)
{
    if (tok_eq(t, "on") || tok_eq(t, "1") || tok_eq(t, "yes")) {
        *out = 1u;
        return 0;
    }
    if (tok_eq(t, "off") || tok_eq(t, "0") || tok_eq(t, "no")) {
        *out = 0u;
        return 0;
    }
    return -1;
}

/* block = motor|output|fixed ORDER Q [on|off] */
static int parse_block(hd_fw_config_t *c, const tok_t *v, size_t nv, bool *blocks_seen,
                       hd_cfgtxt_error_t *err, unsigned line)
{
    if (nv < 3u || nv > 4u) {
        return fail(err, HD_CFGTXT_ERR_SYNTAX, line,
                    "block needs: motor|output|fixed <order_or_hz> <q_nm2> [on|off]");
    }
    hd_kf_block_config_t b = {0};
    if (tok_eq(v[0], "motor")) {
        b.lock = HD_KF_LOCK_MOTOR;
    } else if (tok_eq(v[0], "output")) {
        b.lock = HD_KF_LOCK_OUTPUT;
    } else if (tok_eq(v[0], "fixed")) {
        b.lock = HD_KF_LOCK_FIXED;
    } else {
        return fail(err, HD_CFGTXT_ERR_SYNTAX, line, "block kind must be motor, output or fixed");
    }
    if (hd_config_parse_float(v[1].s, v[1].n, &b.order) != 0 ||
        hd_config_parse_float(v[2].s, v[2].n, &b.q_nm2) != 0) {
        return fail(err, HD_CFGTXT_ERR_SYNTAX, line, "block order and q must be numbers");
    }
    if (b.order <= 0.0f || b.q_nm2 < 0.0f) {
        return fail(err, HD_CFGTXT_ERR_RANGE, line, "block order must be > 0 and q >= 0");
    }
    if (b.lock == HD_KF_LOCK_FIXED && b.order >= 0.5f / HD_FW_TS_S) {
        return fail(err, HD_CFGTXT_ERR_RANGE, line, "fixed block frequency must be below 500 Hz");
    }
    b.enabled = 1u;
    if (nv == 4u && parse_on_off(v[3], &b.enabled) != 0) {
        return fail(err, HD_CFGTXT_ERR_SYNTAX, line, "block state must be on or off");
    }
    if (!*blocks_seen) {
        c->kf.block_count = 0u; /* the file's blocks replace the inherited ones */
        *blocks_seen = true;
    }
    if (c->kf.block_count >= HD_KF_MAX_BLOCKS) {
        return fail(err, HD_CFGTXT_ERR_TOO_MANY_BLOCKS, line, "too many blocks");
    }
    c->kf.blocks[c->kf.block_count++] = b;
    return HD_CFGTXT_OK;
}

static int parse_line(hd_fw_config_t *c, const char *s, size_t n, bool *blocks_seen,
                      hd_cfgtxt_error_t *err, unsigned line)
{
    /* strip the comment */
    for (size_t i = 0; i < n; i++) {
        if (s[i] == '#') {
            n = i;
            break;
        }
    }
    /* key, then an optional '=' (attached or not), then values */
    size_t i = 0;
    while (i < n && is_space(s[i])) {
        i++;
    }
    if (i == n) {
        return HD_CFGTXT_OK; /* blank */
    }
    size_t k0 = i;
    while (i < n && !is_space(s[i]) && s[i] != '=') {
        i++;
    }
    tok_t key = {s + k0, i - k0};
    while (i < n && is_space(s[i])) {
        i++;
    }
    if (i < n && s[i] == '=') {
        i++;
    }
    tok_t v[5];
    size_t nv = split(s + i, n - i, v, 4u);
    if (nv == 0u) {
        return fail(err, HD_CFGTXT_ERR_SYNTAX, line, "missing value");
    }
    if (nv > 4u) {
        return fail(err, HD_CFGTXT_ERR_SYNTAX, line, "too many values");
    }
    if (tok_eq(key, "block")) {
        return parse_block(c, v, nv, blocks_seen, err, line);
    }
    if (nv != 1u) {
        return fail(err, HD_CFGTXT_ERR_SYNTAX, line, "this key takes one value");
    }
    for (size_t f = 0; f < sizeof FLOAT_KEYS / sizeof FLOAT_KEYS[0]; f++) {
        if (!tok_eq(key, FLOAT_KEYS[f].key)) {
            continue;
        }
        float x;
        if (hd_config_parse_float(v[0].s, v[0].n, &x) != 0) {
            return fail(err, HD_CFGTXT_ERR_SYNTAX, line, "value is not a finite number");
        }
        if ((FLOAT_KEYS[f].rule == V_POS && !(x > 0.0f)) ||
            (FLOAT_KEYS[f].rule == V_NONNEG && !(x >= 0.0f))) {
            return fail(err, HD_CFGTXT_ERR_RANGE, line,
                        FLOAT_KEYS[f].rule == V_POS ? "value must be > 0" : "value must be >= 0");
        }
        memcpy((char *)c + FLOAT_KEYS[f].offset, &x, sizeof x);
        return HD_CFGTXT_OK;
    }
    if (tok_eq(key, "offset") || tok_eq(key, "offset_is_sensor_error") || tok_eq(key, "filter")) {
        uint8_t on;
        if (parse_on_off(v[0], &on) != 0) {
            return fail(err, HD_CFGTXT_ERR_SYNTAX, line, "value must be on or off");
        }
        if (tok_eq(key, "offset")) {
            c->kf.offset_enabled = on;
        } else if (tok_eq(key, "filter")) {
            c->filter_enabled = on;
        } else {
            c->kf.offset_is_sensor_error = on;
        }
        return HD_CFGTXT_OK;
    }
    uint32_t u;
    if (tok_eq(key, "telemetry_rate_hz") || tok_eq(key, "node_id") || tok_eq(key, "motor_cpr") ||
        tok_eq(key, "output_cpr")) {
        bool rate = tok_eq(key, "telemetry_rate_hz");
        bool node = tok_eq(key, "node_id");
        uint32_t max = rate ? HD_FW_TICK_HZ : (node ? HD_CAN_NODE_MAX : 0x7FFFFFFFu);
        int rc = parse_uint(v[0], max, &u);
        if (rc == -1) {
            return fail(err, HD_CFGTXT_ERR_SYNTAX, line, "value must be a non-negative integer");
        }
        if (rc == -2 || (node && u < HD_CAN_NODE_MIN) || (!rate && !node && u == 0u)) {
            return fail(err, HD_CFGTXT_ERR_RANGE, line,
                        rate ? "telemetry_rate_hz must be 0..1000"
                             : (node ? "node_id must be 1..127" : "encoder cpr must be >= 1"));
        }
        if (rate) {
            c->telemetry_rate_hz = (uint16_t)u;
        } else if (node) {
            c->node_id = (uint8_t)u;
        } else if (tok_eq(key, "motor_cpr")) {
            c->motor_cpr = u;
        } else {
            c->output_cpr = u;
        }
        return HD_CFGTXT_OK;
    }
    return fail(err, HD_CFGTXT_ERR_UNKNOWN_KEY, line, "unknown key");
}

int hd_config_text_parse(const char *text, size_t len, hd_fw_config_t *cfg,
                         hd_cfgtxt_error_t *err)
{
    if (cfg == NULL || (text == NULL && len > 0u)) {
        return fail(err, HD_CFGTXT_ERR_NULL, 0u, "null argument");
    }
    hd_fw_config_t work = *cfg; /* all or nothing: *cfg changes only on success */
    bool blocks_seen = false;
    unsigned line = 1;
    size_t start = 0;
    while (start < len) {
        size_t end = start;
        while (end < len && text[end] != '\n' && text[end] != '\0') {
            end++;
        }
        if (end - start > HD_CFGTXT_MAX_LINE) {
            return fail(err, HD_CFGTXT_ERR_SYNTAX, line, "line too long");
        }
        int rc = parse_line(&work, text + start, end - start, &blocks_seen, err, line);
        if (rc != HD_CFGTXT_OK) {
            return rc;
        }
        if (end < len && text[end] == '\0') {
            break;
        }
        start = end + 1u;
        line++;
    }
    int frc = hd_fw_config_check(&work);
    if (frc != HD_FW_OK) {
        fail(err, HD_CFGTXT_ERR_CONFIG, 0u, hd_fw_err_str(frc));
        if (err != NULL) {
            err->fw_err = frc;
        }
        return HD_CFGTXT_ERR_CONFIG;
    }
    *cfg = work;
    if (err != NULL) {
        err->code = HD_CFGTXT_OK;
        err->line = 0u;
        err->message = "ok";
        err->fw_err = 0;
    }
    return HD_CFGTXT_OK;
}
