#include "hd_sim_scenario.h"

#include "hd_hostio.h"

#include <ctype.h>
#include <errno.h>
#include <math.h>
#include <stdarg.h>
#include <stdio.h>
#include <stdlib.h>
#include <string.h>

#define LINE_MAX_CHARS 4096

/* ------------------------------------------------------------------ defaults */

void hd_sim_scenario_default(hd_sim_scenario_t *sc)
{
    memset(sc, 0, sizeof(*sc));
    sc->duration_s = 10.0;
    sc->ts_s = 0.001;
    sc->seed = 1;
    sc->gear_ratio = 100.0;
    sc->motor_speed.n = 2;
    sc->motor_speed.t_s[0] = 0.0;
    sc->motor_speed.value[0] = 0.0;
    sc->motor_speed.t_s[1] = 0.5;
    sc->motor_speed.value[1] = 156.0;
    sc->load_inertia_kgm2 = 0.1;
    sc->viscous_nm_s_rad = 1.0;
    sc->coulomb_nm = 1.0;
    sc->stribeck_velocity_rad_s = 0.05;
    hd_bridge_config_default(&sc->bridge);
    sc->adc_bits = 16;
    sc->adc_range_v = 10.0;
    sc->encoder_cpr = 4096;
    sc->cal_gain_nm_per_v = (double)NAN;
    sc->cal_offset_v = (double)NAN;
    sc->ff.gravity_scale = 1.0;
    sc->ff.period_ms = 1u;
    sc->motor.efficiency = 1.0;
    sc->motor.backdrive_efficiency = 1.0;
}

/* ------------------------------------------------------------------ helpers */

static void fail(char *err, size_t len, const char *fmt, ...)
{
    if (err == NULL || len == 0) {
        return;
    }
    va_list ap;
    va_start(ap, fmt);
    vsnprintf(err, len, fmt, ap);
    va_end(ap);
}

static char *trim(char *s)
{
    while (isspace((unsigned char)*s)) {
        s++;
    }
    char *e = s + strlen(s);
    while (e > s && isspace((unsigned char)e[-1])) {
        *--e = '\0';
    }
    return s;
}

/* A finite double that fills the whole (trimmed) token. */
static int parse_double(const char *tok, double *out)
{
    char buf[128];
    size_t n = strlen(tok);
    if (n == 0 || n >= sizeof(buf)) {
        return -1;
    }
    memcpy(buf, tok, n + 1);
    char *s = trim(buf);
    if (*s == '\0') {
        return -1;
    }
    if (strpbrk(s, "xX") != NULL) {
        return -1; /* strtod would take C99 hex floats: decimal only */
    }
    char *end = NULL;
    errno = 0;
    double v = strtod(s, &end);
    if (end == s || *end != '\0' || errno == ERANGE || !isfinite(v)) {
        return -1;
    }
    *out = v;
    return 0;
}

/* A decimal integer: digits only, no sign, no leading zero (strtoull with
 * base 0 would read "01024" as octal 532 and "0x10" as hex). */
static int parse_u64(const char *tok, uint64_t *out)
{
    while (isspace((unsigned char)*tok)) {
        tok++;
    }
    const char *p = tok;
    while (isdigit((unsigned char)*p)) {
        p++;
    }
    const char *end = p;
    while (isspace((unsigned char)*p)) {
        p++;
    }
    if (end == tok || *p != '\0') {
        return -1;
    }
    if (tok[0] == '0' && end - tok > 1) {
        return -2;
    }
    uint64_t v = 0;
    for (const char *q = tok; q < end; q++) {
        const uint64_t d = (uint64_t)(*q - '0');
        if (v > (UINT64_MAX - d) / 10u) {
            return -1;
        }
        v = v * 10u + d;
    }
    *out = v;
    return 0;
}

/* Split s (modified in place) at sep into at most max fields. */
static size_t split(char *s, char sep, char **fields, size_t max)
{
    size_t n = 0;
    char *p = s;
    for (;;) {
        char *q = strchr(p, sep);
        if (n == max) {
            return max + 1; /* too many */
        }
        fields[n++] = p;
        if (q == NULL) {
            break;
        }
        *q = '\0';
        p = q + 1;
    }
    return n;
}

/* ------------------------------------------------------------------ value parsers */

static int parse_profile(char *v, hd_sim_profile_t *p, char *err, size_t len)
{
    char *pts[HD_SIM_MAX_POINTS + 1];
    size_t n = split(v, ',', pts, HD_SIM_MAX_POINTS);
    if (n > HD_SIM_MAX_POINTS) {
        fail(err, len, "profile has more than %d points", HD_SIM_MAX_POINTS);
        return -1;
    }
    hd_sim_profile_t tmp;
    tmp.n = n;
    for (size_t i = 0; i < n; i++) {
        char *tv[3];
        if (split(pts[i], ':', tv, 2) != 2 || parse_double(tv[0], &tmp.t_s[i]) != 0 ||
            parse_double(tv[1], &tmp.value[i]) != 0) {
            fail(err, len, "profile point %zu: expected \"time_s:value\"", i + 1);
            return -1;
        }
        if (tmp.t_s[i] < 0.0) {
            fail(err, len, "profile point %zu: time %g s is negative", i + 1, tmp.t_s[i]);
            return -1;
        }
        if (i > 0 && !(tmp.t_s[i] > tmp.t_s[i - 1])) {
            fail(err, len, "profile point %zu: times must increase strictly (%g after %g)",
                 i + 1, tmp.t_s[i], tmp.t_s[i - 1]);
            return -1;
        }
    }
    *p = tmp;
    return 0;
}

static int parse_ripple(char *v, hd_sim_scenario_t *sc, char *err, size_t len)
{
    if (sc->ripple_count >= HD_SIM_MAX_RIPPLES) {
        fail(err, len, "more than %d ripple lines", HD_SIM_MAX_RIPPLES);
        return -1;
    }
    char *f[5];
    size_t n = split(v, ':', f, 4);
    if (n != 4) {
        fail(err, len, "ripple: expected \"motor|output|fixed : order_or_hz : amplitude_nm : phase_rad\"");
        return -1;
    }
    hd_sim_ripple_t r;
    char *kind = trim(f[0]);
    if (strcmp(kind, "motor") == 0) {
        r.kind = HD_SIM_RIPPLE_MOTOR;
    } else if (strcmp(kind, "output") == 0) {
        r.kind = HD_SIM_RIPPLE_OUTPUT;
    } else if (strcmp(kind, "fixed") == 0) {
        r.kind = HD_SIM_RIPPLE_FIXED;
    } else {
        fail(err, len, "ripple: unknown kind \"%s\" (motor, output or fixed)", kind);
        return -1;
    }
    if (parse_double(f[1], &r.order) != 0 || !(r.order > 0.0)) {
        fail(err, len, "ripple: order/frequency must be a number > 0");
        return -1;
    }
    if (parse_double(f[2], &r.amplitude_nm) != 0 || r.amplitude_nm < 0.0) {
        fail(err, len, "ripple: amplitude must be a number >= 0 (N m)");
        return -1;
    }
    if (parse_double(f[3], &r.phase_rad) != 0) {
        fail(err, len, "ripple: phase must be a number (rad)");
        return -1;
    }
    sc->ripples[sc->ripple_count++] = r;
    return 0;
}

static int parse_window_into(char *v, const char *key, hd_sim_window_t *list, size_t *count,
                             char *err, size_t len)
{
    if (*count >= HD_SIM_MAX_FAULTS) {
        fail(err, len, "more than %d %s windows", HD_SIM_MAX_FAULTS, key);
        return -1;
    }
    char *f[3];
    hd_sim_window_t w;
    if (split(v, ':', f, 2) != 2 || parse_double(f[0], &w.t_start_s) != 0 ||
        parse_double(f[1], &w.t_end_s) != 0 || w.t_start_s < 0.0 || !(w.t_end_s > w.t_start_s)) {
        fail(err, len, "%s: expected \"t_start_s:t_end_s\" with 0 <= start < end", key);
        return -1;
    }
    list[(*count)++] = w;
    return 0;
}

static int parse_window(char *v, hd_sim_scenario_t *sc, char *err, size_t len)
{
    if (sc->encoder_fault_count >= HD_SIM_MAX_FAULTS) {
        fail(err, len, "more than %d encoder fault windows", HD_SIM_MAX_FAULTS);
        return -1;
    }
    return parse_window_into(v, "encoder_fault", sc->encoder_faults, &sc->encoder_fault_count,
                             err, len);
}

static int parse_sine(char *v, hd_sim_scenario_t *sc, char *err, size_t len)
{
    if (sc->load_sine_count >= HD_SIM_MAX_SINES) {
        fail(err, len, "more than %d load_sine components", HD_SIM_MAX_SINES);
        return -1;
    }
    char *f[4];
    hd_sim_sine_t w;
    if (split(v, ':', f, 3) != 3 || parse_double(f[0], &w.amplitude_nm) != 0 ||
        parse_double(f[1], &w.period_s) != 0 || parse_double(f[2], &w.phase_rad) != 0 ||
        !(w.period_s > 0.0)) {
        fail(err, len, "load_sine: expected \"amplitude_nm : period_s : phase_rad\" with period > 0");
        return -1;
    }
    sc->load_sines[sc->load_sine_count++] = w;
    return 0;
}

static int parse_placement(char *v, hd_sim_scenario_t *sc, char *err, size_t len)
{
    char *f[HD_BRIDGE_ROSETTES + 1];
    size_t n = split(v, ',', f, HD_BRIDGE_ROSETTES);
    if (n != HD_BRIDGE_ROSETTES) {
        fail(err, len, "bridge.placement_error_rad: expected %d comma-separated angles (rad)",
             HD_BRIDGE_ROSETTES);
        return -1;
    }
    float tmp[HD_BRIDGE_ROSETTES];
    for (size_t i = 0; i < n; i++) {
        double d;
        if (parse_double(f[i], &d) != 0 || fabs(d) > 0.5) {
            fail(err, len, "bridge.placement_error_rad: value %zu must be a number with |x| <= 0.5 rad",
                 i + 1);
            return -1;
        }
        tmp[i] = (float)d;
    }
    memcpy(sc->bridge.placement_error_rad, tmp, sizeof(tmp));
    return 0;
}

/* ------------------------------------------------------------------ key table */

typedef enum {
    K_DOUBLE_ANY,
    K_DOUBLE_NONNEG,
    K_DOUBLE_POS,
    K_FLOAT_POS,   /* float field in the bridge config */
    K_FLOAT_NONNEG,
    K_U64,
    K_U32,
    K_INT,
    K_PROFILE,
    K_RIPPLE,      /* list */
    K_WINDOW,      /* list */
    K_PLACEMENT,
    K_SINE,        /* list */
    K_FF_DROPOUT,  /* list */
} key_type_t;

typedef struct {
    const char *name;
    key_type_t type;
    size_t offset;
} key_def_t;

#define F(field) offsetof(hd_sim_scenario_t, field)

static const key_def_t KEYS[] = {
    {"duration_s", K_DOUBLE_POS, F(duration_s)},
    {"ts_s", K_DOUBLE_POS, F(ts_s)},
    {"seed", K_U64, F(seed)},
    {"gear_ratio", K_DOUBLE_POS, F(gear_ratio)},
    {"motor_angle0_rad", K_DOUBLE_ANY, F(motor_angle0_rad)},
    {"motor_speed_profile", K_PROFILE, F(motor_speed)},
    {"load_torque_profile", K_PROFILE, F(load_torque)},
    {"load_inertia_kgm2", K_DOUBLE_NONNEG, F(load_inertia_kgm2)},
    {"viscous_nm_s_rad", K_DOUBLE_NONNEG, F(viscous_nm_s_rad)},
    {"coulomb_nm", K_DOUBLE_NONNEG, F(coulomb_nm)},
    {"stribeck_nm", K_DOUBLE_NONNEG, F(stribeck_nm)},
    {"stribeck_velocity_rad_s", K_DOUBLE_POS, F(stribeck_velocity_rad_s)},
    {"ripple", K_RIPPLE, 0},
    {"ripple_load_coeff_per_nm", K_DOUBLE_ANY, F(ripple_load_coeff_per_nm)},
    {"offset_nm", K_DOUBLE_ANY, F(offset_nm)},
    {"offset_drift_nm_per_s", K_DOUBLE_ANY, F(offset_drift_nm_per_s)},
    {"offset_random_walk_nm_per_sqrt_s", K_DOUBLE_NONNEG, F(offset_random_walk_nm_per_sqrt_s)},
    {"noise_nm", K_DOUBLE_NONNEG, F(noise_nm)},
    {"noise_v", K_DOUBLE_NONNEG, F(noise_v)},
    {"bridge.gauge_factor", K_FLOAT_POS, F(bridge.gauge_factor)},
    {"bridge.supply_v", K_FLOAT_POS, F(bridge.supply_v)},
    {"bridge.amp_gain", K_FLOAT_POS, F(bridge.amp_gain)},
    {"bridge.strain_per_nm", K_FLOAT_POS, F(bridge.strain_per_nm)},
    {"bridge.psi0", K_FLOAT_NONNEG, F(bridge.psi0)},
    {"bridge.placement_error_rad", K_PLACEMENT, 0},
    {"bridge.offset_v", K_DOUBLE_ANY, F(bridge_offset_v)},
    {"adc_bits", K_INT, F(adc_bits)},
    {"adc_range_v", K_DOUBLE_POS, F(adc_range_v)},
    {"encoder_cpr", K_U32, F(encoder_cpr)},
    {"output_encoder_cpr", K_U32, F(output_encoder_cpr)},
    {"encoder_fault", K_WINDOW, 0},
    {"calibration.gain_nm_per_v", K_DOUBLE_POS, F(cal_gain_nm_per_v)},
    {"calibration.offset_v", K_DOUBLE_ANY, F(cal_offset_v)},
    {"gravity_profile", K_PROFILE, F(gravity)},
    {"gravity_phase_rad", K_DOUBLE_ANY, F(gravity_phase_rad)},
    {"load_sine", K_SINE, 0},
    {"feedforward", K_INT, F(ff.enabled)},
    {"feedforward.gravity_scale", K_DOUBLE_ANY, F(ff.gravity_scale)},
    {"feedforward.gravity_phase_error_rad", K_DOUBLE_ANY, F(ff.gravity_phase_error_rad)},
    {"feedforward.gravity_profile", K_PROFILE, F(ff.gravity)},
    {"feedforward.load_scale", K_DOUBLE_ANY, F(ff.load_scale)},
    {"feedforward.inertia_kgm2", K_DOUBLE_NONNEG, F(ff.inertia_kgm2)},
    {"feedforward.viscous_nm_s_rad", K_DOUBLE_NONNEG, F(ff.viscous_nm_s_rad)},
    {"feedforward.coulomb_nm", K_DOUBLE_NONNEG, F(ff.coulomb_nm)},
    {"feedforward.noise_nm", K_DOUBLE_NONNEG, F(ff.noise_nm)},
    {"feedforward.period_ms", K_U32, F(ff.period_ms)},
    {"feedforward.dropout", K_FF_DROPOUT, 0},
    {"motor.kt_nm_per_a", K_DOUBLE_NONNEG, F(motor.kt_nm_per_a)},
    {"motor.kt_error", K_DOUBLE_ANY, F(motor.kt_error)},
    {"motor.efficiency", K_DOUBLE_POS, F(motor.efficiency)},
    {"motor.backdrive_efficiency", K_DOUBLE_POS, F(motor.backdrive_efficiency)},
    {"motor.coulomb_nm", K_DOUBLE_NONNEG, F(motor.coulomb_nm)},
    {"motor.viscous_nm_s_rad", K_DOUBLE_NONNEG, F(motor.viscous_nm_s_rad)},
    {"motor.inertia_kgm2", K_DOUBLE_NONNEG, F(motor.inertia_kgm2)},
    {"motor.current_noise_a", K_DOUBLE_NONNEG, F(motor.current_noise_a)},
};
#define N_KEYS (sizeof(KEYS) / sizeof(KEYS[0]))

static const key_def_t *find_key(const char *name, size_t *index)
{
    for (size_t i = 0; i < N_KEYS; i++) {
        if (strcmp(KEYS[i].name, name) == 0) {
            *index = i;
            return &KEYS[i];
        }
    }
    return NULL;
}

static int apply(hd_sim_scenario_t *sc, const key_def_t *k, char *v, char *err, size_t len)
{
    char *base = (char *)sc + k->offset;
    double d = 0.0;
    uint64_t u = 0;
    char sub[256];
    switch (k->type) {
    case K_DOUBLE_ANY:
    case K_DOUBLE_NONNEG:
    case K_DOUBLE_POS:
    case K_FLOAT_POS:
    case K_FLOAT_NONNEG:
        if (parse_double(v, &d) != 0) {
            fail(err, len, "%s: \"%s\" is not a finite number", k->name, v);
            return -1;
        }
        if ((k->type == K_DOUBLE_POS || k->type == K_FLOAT_POS) && !(d > 0.0)) {
            fail(err, len, "%s: must be > 0 (got %g)", k->name, d);
            return -1;
        }
        if ((k->type == K_DOUBLE_NONNEG || k->type == K_FLOAT_NONNEG) && d < 0.0) {
            fail(err, len, "%s: must be >= 0 (got %g)", k->name, d);
            return -1;
        }
        if (k->type == K_FLOAT_POS || k->type == K_FLOAT_NONNEG) {
            float f = (float)d;
            memcpy(base, &f, sizeof(f));
        } else {
            memcpy(base, &d, sizeof(d));
        }
        return 0;
    case K_U64:
    case K_U32:
    case K_INT:
        switch (parse_u64(v, &u)) {
        case 0:
            break;
        case -2:
            fail(err, len, "%s: \"%s\" has a leading zero (integers are decimal)", k->name, v);
            return -1;
        default:
            fail(err, len, "%s: \"%s\" is not a non-negative decimal integer", k->name, v);
            return -1;
        }
        if (k->type == K_U64) {
            memcpy(base, &u, sizeof(u));
        } else if (k->type == K_U32) {
            if (u > UINT32_MAX) {
                fail(err, len, "%s: %llu exceeds 2^32-1", k->name, (unsigned long long)u);
                return -1;
            }
            uint32_t w = (uint32_t)u;
            memcpy(base, &w, sizeof(w));
        } else {
            if (u > 64) {
                fail(err, len, "%s: %llu is too large", k->name, (unsigned long long)u);
                return -1;
            }
            int i = (int)u;
            memcpy(base, &i, sizeof(i));
        }
        return 0;
    case K_PROFILE:
        if (parse_profile(v, (hd_sim_profile_t *)(void *)base, sub, sizeof(sub)) != 0) {
            fail(err, len, "%s: %s", k->name, sub);
            return -1;
        }
        return 0;
    case K_RIPPLE:
        return parse_ripple(v, sc, err, len);
    case K_WINDOW:
        return parse_window(v, sc, err, len);
    case K_PLACEMENT:
        return parse_placement(v, sc, err, len);
    case K_SINE:
        return parse_sine(v, sc, err, len);
    case K_FF_DROPOUT:
        return parse_window_into(v, "feedforward.dropout", sc->ff.dropouts, &sc->ff.dropout_count,
                                 err, len);
    }
    return -1;
}

/* Strip one pair of surrounding double quotes. */
static char *unquote(char *v)
{
    size_t n = strlen(v);
    if (n >= 2 && v[0] == '"' && v[n - 1] == '"') {
        v[n - 1] = '\0';
        return v + 1;
    }
    return v;
}

int hd_sim_scenario_set(hd_sim_scenario_t *sc, const char *key, const char *value,
                        char *err, size_t err_len)
{
    char buf[LINE_MAX_CHARS];
    size_t idx;
    const key_def_t *k = find_key(key, &idx);
    if (k == NULL) {
        fail(err, err_len, "unknown key \"%s\"", key);
        return -1;
    }
    if (strlen(value) >= sizeof(buf)) {
        fail(err, err_len, "%s: value too long", key);
        return -1;
    }
    strcpy(buf, value);
    return apply(sc, k, unquote(trim(buf)), err, err_len);
}

/* Text is printable ASCII, tab, CR, or valid UTF-8 (in comments): anything
 * else means the file is not a scenario (or is damaged).  Returns the column
 * (1-based) of the first bad byte, or 0. */
static size_t bad_byte(const unsigned char *p, size_t n, char *what, size_t what_len)
{
    for (size_t i = 0; i < n; i++) {
        const unsigned char c = p[i];
        if (c == 0u) {
            fail(what, what_len, "NUL byte");
            return i + 1u;
        }
        if ((c < 0x20u && c != '\t' && c != '\r') || c == 0x7Fu) {
            fail(what, what_len, "control character 0x%02X", (unsigned)c);
            return i + 1u;
        }
        if (c < 0x80u) {
            continue;
        }
        /* UTF-8: lead byte, then 1..3 continuation bytes (no overlongs
         * beyond the lead-byte ranges, no surrogate check: a comment). */
        size_t more = (c >= 0xC2u && c <= 0xDFu) ? 1u
                      : (c >= 0xE0u && c <= 0xEFu) ? 2u
                      : (c >= 0xF0u && c <= 0xF4u) ? 3u : 0u;
        if (more == 0u || more >= n - i) {
            fail(what, what_len, "byte 0x%02X is not UTF-8 text", (unsigned)c);
            return i + 1u;
        }
        for (size_t k = 1; k <= more; k++) {
            if ((p[i + k] & 0xC0u) != 0x80u) {
                fail(what, what_len, "byte 0x%02X is not UTF-8 text", (unsigned)c);
                return i + 1u;
            }
        }
        i += more;
    }
    return 0u;
}

int hd_sim_scenario_parse_n(hd_sim_scenario_t *sc, const char *text, size_t text_len,
                            const char *name, char *err, size_t err_len)
{
    unsigned seen_line[N_KEYS];
    memset(seen_line, 0, sizeof(seen_line));
    char line[LINE_MAX_CHARS];
    char msg[512];
    const char *p = text;
    const char *text_end = text + text_len;
    unsigned lineno = 0;
    while (p < text_end) {
        lineno++;
        const char *nl = memchr(p, '\n', (size_t)(text_end - p));
        size_t n = nl != NULL ? (size_t)(nl - p) : (size_t)(text_end - p);
        size_t col = bad_byte((const unsigned char *)p, n, msg, sizeof(msg));
        if (col != 0u) {
            fail(err, err_len, "%s:%u: %s at column %zu: not a text file", name, lineno, msg,
                 col);
            return -1;
        }
        if (n >= sizeof(line)) {
            fail(err, err_len, "%s:%u: line longer than %d characters", name, lineno,
                 LINE_MAX_CHARS - 1);
            return -1;
        }
        memcpy(line, p, n);
        line[n] = '\0';
        p += n + (nl != NULL ? 1 : 0);

        char *hash = strchr(line, '#');
        if (hash != NULL) {
            *hash = '\0';
        }
        char *s = trim(line);
        if (*s == '\0') {
            continue;
        }
        char *eq = strchr(s, '=');
        if (eq == NULL) {
            fail(err, err_len, "%s:%u: expected \"key = value\", got \"%s\"", name, lineno, s);
            return -1;
        }
        *eq = '\0';
        char *key = trim(s);
        char *val = unquote(trim(eq + 1));
        size_t idx;
        const key_def_t *k = find_key(key, &idx);
        if (k == NULL) {
            fail(err, err_len, "%s:%u: unknown key \"%s\" (see docs/reference/sim.md)", name, lineno, key);
            return -1;
        }
        if (*val == '\0') {
            fail(err, err_len, "%s:%u: %s: empty value", name, lineno, key);
            return -1;
        }
        const int is_list = (k->type == K_RIPPLE || k->type == K_WINDOW || k->type == K_SINE ||
                             k->type == K_FF_DROPOUT);
        if (!is_list && seen_line[idx] != 0u) {
            fail(err, err_len, "%s:%u: %s given twice (first on line %u)", name, lineno, key,
                 seen_line[idx]);
            return -1;
        }
        if (seen_line[idx] == 0u) {
            seen_line[idx] = lineno;
        }
        if (apply(sc, k, val, msg, sizeof(msg)) != 0) {
            fail(err, err_len, "%s:%u: %s", name, lineno, msg);
            return -1;
        }
    }
    if (hd_sim_scenario_validate(sc, msg, sizeof(msg)) != 0) {
        fail(err, err_len, "%s: %s", name, msg);
        return -1;
    }
    return 0;
}

int hd_sim_scenario_parse(hd_sim_scenario_t *sc, const char *text, const char *name,
                          char *err, size_t err_len)
{
    return hd_sim_scenario_parse_n(sc, text, strlen(text), name, err, err_len);
}

int hd_sim_scenario_load(hd_sim_scenario_t *sc, const char *path, char *err, size_t err_len)
{
    size_t n = 0;
    char *buf = hd_hostio_read_file(path, HD_HOSTIO_TEXT_MAX_BYTES, &n, err, err_len);
    if (buf == NULL) {
        return -1;
    }
    int rc = hd_sim_scenario_parse_n(sc, buf, n, path, err, err_len);
    free(buf);
    return rc;
}

/* ------------------------------------------------------------------ checks */

uint64_t hd_sim_scenario_samples(const hd_sim_scenario_t *sc)
{
    double n = floor(sc->duration_s / sc->ts_s + 0.5);
    if (!(n >= 0.0)) {
        return 0;
    }
    if (n > (double)HD_SIM_MAX_SAMPLES) {
        return HD_SIM_MAX_SAMPLES + 1;
    }
    return (uint64_t)n;
}

int hd_sim_scenario_validate(const hd_sim_scenario_t *sc, char *err, size_t err_len)
{
    if (!(sc->ts_s > 0.0) || sc->ts_s > 1.0) {
        fail(err, err_len, "ts_s must be in (0, 1] s");
        return -1;
    }
    const double ts_us = sc->ts_s * 1e6;
    if (fabs(ts_us - floor(ts_us + 0.5)) > 1e-6 * ts_us || ts_us < 1.0) {
        fail(err, err_len, "ts_s must be a whole number of microseconds (raw stream stores ts_us)");
        return -1;
    }
    const uint64_t n = hd_sim_scenario_samples(sc);
    if (n == 0) {
        fail(err, err_len, "duration_s shorter than one sample");
        return -1;
    }
    if (n > HD_SIM_MAX_SAMPLES) {
        fail(err, err_len, "duration_s / ts_s exceeds %llu samples",
             (unsigned long long)HD_SIM_MAX_SAMPLES);
        return -1;
    }
    if (!(sc->gear_ratio > 0.0) || !isfinite(sc->gear_ratio)) {
        fail(err, err_len, "gear_ratio must be > 0");
        return -1;
    }
    if (sc->adc_bits < 8 || sc->adc_bits > 24) {
        fail(err, err_len, "adc_bits must be in [8, 24] (got %d)", sc->adc_bits);
        return -1;
    }
    if (sc->encoder_cpr == 0) {
        fail(err, err_len, "encoder_cpr must be >= 1");
        return -1;
    }
    if (!isfinite(hd_bridge_gain_nm_per_v(&sc->bridge))) {
        fail(err, err_len, "bridge: gain is not finite");
        return -1;
    }
    if (sc->ff.enabled != 0 && sc->ff.enabled != 1) {
        fail(err, err_len, "feedforward must be 0 or 1 (got %d)", sc->ff.enabled);
        return -1;
    }
    if (sc->ff.period_ms < 1u || sc->ff.period_ms > 1000000u) {
        fail(err, err_len, "feedforward.period_ms must be in [1, 1000000] samples");
        return -1;
    }
    if (sc->motor.efficiency > 1.0 || sc->motor.backdrive_efficiency > 1.0) {
        fail(err, err_len, "motor.efficiency and motor.backdrive_efficiency must be in (0, 1]");
        return -1;
    }
    if (!(sc->motor.kt_error > -1.0)) {
        fail(err, err_len, "motor.kt_error must be > -1 (kt_true = kt (1 + kt_error) > 0)");
        return -1;
    }
    return 0;
}

double hd_sim_profile_eval(const hd_sim_profile_t *p, double t_s)
{
    if (p->n == 0) {
        return 0.0;
    }
    if (t_s <= p->t_s[0]) {
        return p->value[0];
    }
    for (size_t i = 1; i < p->n; i++) {
        if (t_s < p->t_s[i]) {
            const double u = (t_s - p->t_s[i - 1]) / (p->t_s[i] - p->t_s[i - 1]);
            return p->value[i - 1] + u * (p->value[i] - p->value[i - 1]);
        }
    }
    return p->value[p->n - 1];
}
