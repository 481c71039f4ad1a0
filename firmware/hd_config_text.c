/* hd_config_text: see hd_config_text.h and docs/design/firmware.md. */
#include "hd_config_text.h"

#include <math.h> /* isfinite (builtin) */
#include <string.h>

#include "hd_params.h"

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

/* Decimal, no sign, no leading zero (so 01024 is not octal 532 in disguise). */
static int parse_uint(tok_t t, uint32_t *out)
{
    if (t.n == 0u || t.n > 10u || (t.n > 1u && t.s[0] == '0')) {
        return -1;
    }
    uint64_t v = 0;
    for (size_t i = 0; i < t.n; i++) {
        if (!is_digit(t.s[i])) {
            return -1;
        }
        v = v * 10u + (uint64_t)(t.s[i] - '0');
    }
    if (v > 0xFFFFFFFFu) {
        return -1;
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

static int fail(hd_cfgtxt_error_t *err, int code, unsigned line, const char *msg)
{
    if (err != NULL) {
        memset(err, 0, sizeof *err);
        err->code = code;
        err->line = line;
        err->message = msg;
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
        return fail(err, HD_FW_ERR_SYNTAX, line,
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
        return fail(err, HD_FW_ERR_SYNTAX, line, "block kind must be motor, output or fixed");
    }
    if (hd_config_parse_float(v[1].s, v[1].n, &b.order) != 0 ||
        hd_config_parse_float(v[2].s, v[2].n, &b.q_nm2) != 0) {
        return fail(err, HD_FW_ERR_SYNTAX, line, "block order and q must be numbers");
    }
    if (b.order <= 0.0f || b.q_nm2 < 0.0f) {
        return fail(err, HD_FW_ERR_RANGE, line, "block order must be > 0 and q >= 0");
    }
    if (b.lock == HD_KF_LOCK_FIXED && b.order >= 0.5f / HD_FW_TS_S) {
        return fail(err, HD_FW_ERR_RANGE, line, "fixed block frequency must be below 500 Hz");
    }
    b.enabled = 1u;
    if (nv == 4u && parse_on_off(v[3], &b.enabled) != 0) {
        return fail(err, HD_FW_ERR_SYNTAX, line, "block state must be on or off");
    }
    if (!*blocks_seen) {
        c->kf.block_count = 0u; /* the file's blocks replace the inherited ones */
        *blocks_seen = true;
    }
    if (c->kf.block_count >= HD_KF_MAX_BLOCKS) {
        return fail(err, HD_FW_ERR_TOO_MANY_BLOCKS, line, "too many blocks");
    }
    c->kf.blocks[c->kf.block_count++] = b;
    return HD_FW_OK;
}

/* Lines on which each table row was set (0 = not yet), for duplicates. */
typedef hd_cfgtxt_keys_t seen_t;

static int parse_value(const hd_param_info_t *p, tok_t t, float *v)
{
    if (p->type == HD_PT_BOOL) {
        uint8_t on;
        if (parse_on_off(t, &on) != 0) {
            return -1;
        }
        *v = (float)on;
        return 0;
    }
    if (p->type == HD_PT_F32) {
        return hd_config_parse_float(t.s, t.n, v);
    }
    uint32_t u;
    if (parse_uint(t, &u) != 0) {
        return -1;
    }
    *v = (float)u;
    return 0;
}

static int parse_param(hd_fw_config_t *c, tok_t key, tok_t value, seen_t *seen,
                       hd_cfgtxt_error_t *err, unsigned line)
{
    const hd_param_info_t *p = hd_param_by_key(key.s, key.n);
    if (p == NULL) {
        return fail(err, HD_FW_ERR_UNKNOWN_PARAM, line, "unknown key");
    }
    if (p->flags & HD_PF_RO) {
        return fail(err, HD_FW_ERR_READ_ONLY, line, "read-only parameter");
    }
    const size_t row = (size_t)(p - hd_param_at(0)); /* < HD_PARAM_ROWS */
    if (seen->line_of[row] != 0u) {
        int rc = fail(err, HD_FW_ERR_DUPLICATE, line, "key given twice");
        if (err != NULL) {
            err->first_line = seen->line_of[row];
        }
        return rc;
    }
    seen->line_of[row] = line;
    float v;
    if (parse_value(p, value, &v) != 0) {
        return fail(err, HD_FW_ERR_SYNTAX, line,
                    p->type == HD_PT_BOOL  ? "value must be on or off"
                    : p->type == HD_PT_F32 ? "value is not a number (a finite decimal)"
                                           : "value must be a whole decimal number without a leading zero");
    }
    hd_fw_err_t rc = hd_param_set(p, c, v);
    if (rc != HD_FW_OK) {
        int code = fail(err, HD_FW_ERR_RANGE, line, "value outside the parameter's range");
        if (err != NULL) {
            err->param_id = p->id;
        }
        return code;
    }
    return HD_FW_OK;
}

/* Bytes a configuration may hold outside comments: printable ASCII, tab, CR. */
static bool text_byte(unsigned char ch)
{
    return ch == '\t' || ch == '\r' || (ch >= 0x20u && ch < 0x7Fu);
}

/* Length of the UTF-8 sequence starting at s[i] (2..4), or 0 if it is not
 * a well-formed one (overlong forms, surrogates and > U+10FFFF refused). */
static size_t utf8_len(const char *s, size_t i, size_t n)
{
    const unsigned char c = (unsigned char)s[i];
    size_t len = c >= 0xF0u ? 4u : (c >= 0xE0u ? 3u : (c >= 0xC2u ? 2u : 0u));
    if (len == 0u || c > 0xF4u || i + len > n) {
        return 0u;
    }
    for (size_t k = 1; k < len; k++) {
        if (((unsigned char)s[i + k] & 0xC0u) != 0x80u) {
            return 0u;
        }
    }
    const unsigned char c1 = (unsigned char)s[i + 1u];
    if ((c == 0xE0u && c1 < 0xA0u) || (c == 0xEDu && c1 >= 0xA0u) ||
        (c == 0xF0u && c1 < 0x90u) || (c == 0xF4u && c1 >= 0x90u)) {
        return 0u;
    }
    return len;
}

/* Printable ASCII, tab and CR anywhere; UTF-8 text only in comments. */
static int check_bytes(const char *s, size_t n, hd_cfgtxt_error_t *err, unsigned line)
{
    bool comment = false;
    for (size_t i = 0; i < n; i++) {
        unsigned char ch = (unsigned char)s[i];
        comment = comment || ch == '#';
        if (ch == 0u) {
            return fail(err, HD_FW_ERR_BYTES, line, "NUL byte");
        }
        if (ch >= 0x80u) {
            size_t len = comment ? utf8_len(s, i, n) : 0u;
            if (len == 0u) {
                return fail(err, HD_FW_ERR_BYTES, line,
                            comment ? "a comment that is not UTF-8 text"
                                    : "non-ASCII byte outside a comment");
            }
            i += len - 1u;
            continue;
        }
        if (!text_byte(ch)) {
            return fail(err, HD_FW_ERR_BYTES, line, "control byte");
        }
    }
    return HD_FW_OK;
}

static int parse_line(hd_fw_config_t *c, const char *s, size_t n, seen_t *seen,
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
        return HD_FW_OK; /* blank */
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
        return fail(err, HD_FW_ERR_SYNTAX, line, "missing value");
    }
    if (nv > 4u) {
        return fail(err, HD_FW_ERR_SYNTAX, line, "too many values");
    }
    if (tok_eq(key, "block")) {
        return parse_block(c, v, nv, &seen->blocks, err, line);
    }
    if (nv != 1u) {
        return fail(err, HD_FW_ERR_SYNTAX, line, "this key takes one value");
    }
    return parse_param(c, key, v[0], seen, err, line);
}

int hd_config_text_parse(const char *text, size_t len, hd_fw_config_t *cfg,
                         hd_cfgtxt_error_t *err)
{
    return hd_config_text_parse_keys(text, len, cfg, err, NULL);
}

size_t hd_config_text_config_size(void)
{
    return sizeof(hd_fw_config_t);
}

int hd_config_text_block(const hd_fw_config_t *cfg, unsigned i, unsigned *lock, float *order,
                         float *q_nm2, unsigned *enabled)
{
    if (cfg == NULL || i >= cfg->kf.block_count || i >= HD_KF_MAX_BLOCKS) {
        return -1;
    }
    const hd_kf_block_config_t *b = &cfg->kf.blocks[i];
    *lock = b->lock;
    *order = b->order;
    *q_nm2 = b->q_nm2;
    *enabled = b->enabled;
    return 0;
}

int hd_config_text_parse_keys(const char *text, size_t len, hd_fw_config_t *cfg,
                              hd_cfgtxt_error_t *err, hd_cfgtxt_keys_t *keys)
{
    if (cfg == NULL || (text == NULL && len > 0u)) {
        return fail(err, HD_FW_ERR_NULL, 0u, "null argument");
    }
    if (len > HD_CFGTXT_MAX_BYTES) {
        return fail(err, HD_FW_ERR_TOO_LONG, 0u, "file larger than 16384 bytes");
    }
    hd_fw_config_t work = *cfg; /* all or nothing: *cfg changes only on success */
    seen_t seen;
    memset(&seen, 0, sizeof seen);
    unsigned line = 1;
    size_t start = 0;
    while (start < len) {
        size_t end = start;
        while (end < len && text[end] != '\n') {
            end++;
        }
        if (end - start > HD_CFGTXT_MAX_LINE) {
            return fail(err, HD_FW_ERR_SYNTAX, line, "line too long");
        }
        int rc = check_bytes(text + start, end - start, err, line);
        if (rc == HD_FW_OK) {
            rc = parse_line(&work, text + start, end - start, &seen, err, line);
        }
        if (rc != HD_FW_OK) {
            return rc;
        }
        start = end + 1u;
        line++;
    }
    unsigned bad = 0u;
    int frc = hd_fw_config_check(&work, &bad);
    if (frc != HD_FW_OK) {
        fail(err, frc, 0u, hd_fw_err_str(frc));
        if (err != NULL) {
            err->param_id = bad;
        }
        return frc;
    }
    *cfg = work;
    if (keys != NULL) {
        *keys = seen;
    }
    fail(err, HD_FW_OK, 0u, "ok");
    return HD_FW_OK;
}
