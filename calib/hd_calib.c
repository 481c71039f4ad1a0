/* Static calibration analysis (Taghirad 1997, section III).  See hd_calib.h. */
#include "hd_calib.h"
#include "hd_calib_lsq.h"
#include "hd_calib_record.h"

#include <math.h>
#include <string.h>

/* The position fit reuses the point-sized design matrix. */
_Static_assert(HD_CALIB_MAX_EXPERIMENTS <= HD_CALIB_MAX_POINTS, "experiments must fit a design column");

/* ---------------------------------------------------------------- input checks */

static int check_experiment(const hd_calib_experiment_t *e)
{
    if (e->n_points > HD_CALIB_MAX_POINTS) {
        return HD_CALIB_ERR_ARG;
    }
    if (e->n_points < 2u) {
        return HD_CALIB_ERR_TOO_FEW_POINTS;
    }
    if (!finite_f(e->position_deg)) {
        return HD_CALIB_ERR_NONFINITE;
    }
    for (uint32_t i = 0; i < e->n_points; ++i) {
        if (!finite_f(e->torque_nm[i]) || !finite_f(e->bridge_v[i])) {
            return HD_CALIB_ERR_NONFINITE;
        }
        if (e->direction[i] != HD_CALIB_DIR_LOAD && e->direction[i] != HD_CALIB_DIR_UNLOAD) {
            return HD_CALIB_ERR_DIRECTION;
        }
    }
    for (uint32_t i = 1; i < e->n_points; ++i) {
        if (e->torque_nm[i] != e->torque_nm[0]) {
            return HD_CALIB_OK;
        }
    }
    return HD_CALIB_ERR_LOADS_EQUAL;
}

/* ---------------------------------------------------------------- one experiment */

typedef struct {
    float x;                 /* normalised torque of the level */
    float sum_v[2];          /* per direction */
    uint32_t count[2];
} level_t;

static uint32_t group_levels(const hd_calib_experiment_t *e, float fs_nm,
                             level_t lv[HD_CALIB_MAX_POINTS])
{
    /* Weights are placed by hand: points closer than 1e-6 FS are one level. */
    const float tol = 1e-6f * fs_nm;
    uint32_t nl = 0;
    for (uint32_t i = 0; i < e->n_points; ++i) {
        uint32_t j = 0;
        while (j < nl && abs_f(lv[j].x * fs_nm - e->torque_nm[i]) > tol) {
            ++j;
        }
        if (j == nl) {
            memset(&lv[nl], 0, sizeof lv[nl]);
            lv[nl].x = e->torque_nm[i] / fs_nm;
            ++nl;
        }
        uint32_t d = e->direction[i];
        lv[j].sum_v[d] += e->bridge_v[i];
        lv[j].count[d]++;
    }
    return nl;
}

/* Per-level measures; *both_nonzero = the levels other than zero that were
 * read in both directions. */
static void level_measures(const hd_calib_experiment_t *e, float a, float b, float fs_nm,
                               float gain, hd_calib_fit_t *out, uint32_t *both_nonzero)
{
    level_t lv[HD_CALIB_MAX_POINTS];
    uint32_t nl = group_levels(e, fs_nm, lv);
    float nl_max = 0.0f, hy_max = 0.0f;
    *both_nonzero = 0u;
    for (uint32_t j = 0; j < nl; ++j) {
        float mean_l = lv[j].count[0] ? lv[j].sum_v[0] / (float)lv[j].count[0] : 0.0f;
        float mean_u = lv[j].count[1] ? lv[j].sum_v[1] / (float)lv[j].count[1] : 0.0f;
        float mid;
        if (lv[j].count[0] && lv[j].count[1]) {
            /* Midpoint of the branches: hysteresis does not leak into
             * nonlinearity however many points each branch has. */
            mid = 0.5f * (mean_l + mean_u);
            float h = abs_f(mean_u - mean_l);
            hy_max = h > hy_max ? h : hy_max;
            *both_nonzero += (lv[j].x != 0.0f) ? 1u : 0u;
        } else {
            mid = lv[j].count[0] ? mean_l : mean_u;
        }
        float dev = abs_f(mid - (a + b * lv[j].x));
        nl_max = dev > nl_max ? dev : nl_max;
    }
    out->nonlinearity_pct_fs = 100.0f * nl_max * gain / fs_nm;
    out->hysteresis_pct_fs = 100.0f * hy_max * gain / fs_nm;
}

enum { COL_ONE = 0, COL_X, COL_X2, COL_X3, COL_U };

static void fill_design(const hd_calib_experiment_t *e, float fs_nm, design_t *d)
{
    d->n = e->n_points;
    for (uint32_t i = 0; i < e->n_points; ++i) {
        float x = e->torque_nm[i] / fs_nm;
        float sgn = x > 0.0f ? 1.0f : (x < 0.0f ? -1.0f : 0.0f);
        d->x[COL_ONE][i] = 1.0f;
        d->x[COL_X][i] = x;
        d->x[COL_X2][i] = x * x;
        d->x[COL_X3][i] = x * x * x;
        /* Branch term: unloading reads further from zero than loading (lag),
         * in either torque direction; the loop closes at the turning points
         * (|x| = 1) and the branches differ most at low load. */
        d->x[COL_U][i] = (e->direction[i] == HD_CALIB_DIR_UNLOAD ? 0.5f : -0.5f) * sgn *
                         (1.0f - x * x);
    }
}

/* Fits a model made of the first p columns of the order list. */
static void fit_cols(const design_t *all, const uint32_t *cols, uint32_t p,
                     const float *y, lsq_t *out)
{
    design_t d;
    d.n = all->n;
    d.p = p;
    for (uint32_t j = 0; j < p; ++j) {
        memcpy(d.x[j], all->x[cols[j]], all->n * sizeof(float));
    }
    hd_calib_lsq_solve(&d, y, out);
}

int hd_calib_fit_experiment(const hd_calib_experiment_t *e, float alpha,
                            float min_detect_pct_fs, hd_calib_fit_t *out)
{
    if (e == NULL || out == NULL) {
        return HD_CALIB_ERR_ARG;
    }
    memset(out, 0, sizeof *out);
    int err = check_experiment(e);
    if (err != HD_CALIB_OK) {
        return err;
    }
    const uint32_t n = e->n_points;
    float fs_nm = 0.0f;
    for (uint32_t i = 0; i < n; ++i) {
        float t = abs_f(e->torque_nm[i]);
        fs_nm = t > fs_nm ? t : fs_nm;
    }
    /* Normalising torque to [-1, 1] keeps float32 normal equations away. */
    design_t all;
    fill_design(e, fs_nm, &all);

    static const uint32_t line_cols[2] = {COL_ONE, COL_X};
    lsq_t line;
    fit_cols(&all, line_cols, 2u, e->bridge_v, &line);
    if (line.rank < 2u) {
        return HD_CALIB_ERR_LOADS_EQUAL;
    }
    float a = line.beta[COL_ONE], b = line.beta[COL_X];
    if (!(b > 0.0f) || !finite_f(b)) {
        return HD_CALIB_ERR_SLOPE;
    }
    out->n_points = n;
    out->position_deg = e->position_deg;
    out->full_scale_nm = fs_nm;
    /* V = a + b T/fs  =>  gain = fs/b, offset = a; delta method for se. */
    out->gain_nm_per_v = fs_nm / b;
    out->gain_se_nm_per_v = line.se[COL_X] * fs_nm / (b * b);
    out->offset_v = a;
    out->offset_se_v = line.se[COL_ONE];
    out->residual_rms_v = sqrtf(line.rss / (float)n);
    uint32_t both_nonzero = 0u;
    level_measures(e, a, b, fs_nm, out->gain_nm_per_v, out, &both_nonzero);

    /* Significance: nested F-tests in the model 1, x, x^2, x^3, branch. */
    static const uint32_t no_curve[3] = {COL_ONE, COL_X, COL_U};
    static const uint32_t no_branch[4] = {COL_ONE, COL_X, COL_X2, COL_X3};
    static const uint32_t full_cols[5] = {COL_ONE, COL_X, COL_U, COL_X2, COL_X3};
    lsq_t m_nc, m_nb, m_full;
    fit_cols(&all, no_curve, 3u, e->bridge_v, &m_nc);
    fit_cols(&all, no_branch, 4u, e->bridge_v, &m_nb);
    fit_cols(&all, full_cols, 5u, e->bridge_v, &m_full);
    out->nonlinearity_p = hd_calib_nested_pvalue(&m_nc, &m_full, n);
    out->hysteresis_p = hd_calib_nested_pvalue(&m_nb, &m_full, n);
    /* What the data cannot measure is NaN, never a reassuring 0.  Fewer
     * than 3 load levels leave x^2, x^3 dependent on 1, x (any function is
     * affine on two points): the F-test has no column to test, p is NaN. */
    out->nonlinearity_measurable = (uint8_t)finite_f(out->nonlinearity_p);
    out->hysteresis_measurable = (uint8_t)(both_nonzero >= 1u && finite_f(out->hysteresis_p));
    if (!out->nonlinearity_measurable) {
        out->nonlinearity_pct_fs = NAN;
        out->nonlinearity_p = NAN;
    }
    if (!out->hysteresis_measurable) {
        out->hysteresis_pct_fs = NAN;
        out->hysteresis_p = NAN;
    }
    out->nonlinearity_detected = (uint8_t)(out->nonlinearity_p < alpha &&
                                           out->nonlinearity_pct_fs >= min_detect_pct_fs);
    out->hysteresis_detected = (uint8_t)(out->hysteresis_p < alpha &&
                                         out->hysteresis_pct_fs >= min_detect_pct_fs);
    return HD_CALIB_OK;
}

/* ---------------------------------------------------------------- campaign */

void hd_calib_thresholds_default(hd_calib_thresholds_t *t)
{
    if (t == NULL) {
        return;
    }
    t->max_consistency = 0.03f;
    t->max_nonlinearity_pct_fs = 1.0f;
    t->max_hysteresis_pct_fs = 1.0f;
    t->max_position_pct = 2.0f;
    t->alpha = 0.001f;
    t->min_detect_pct_fs = 0.02f;
    t->min_experiments = 2u;
    t->allow_unmeasurable = 0u;
}

static void position_test(const hd_calib_experiment_t *exps, uint32_t n,
                          const hd_calib_thresholds_t *t, hd_calib_report_t *out)
{
    design_t d;
    float g[HD_CALIB_MAX_POINTS] = {0.0f};
    d.n = n;
    d.p = 3u;
    for (uint32_t i = 0; i < n; ++i) {
        float th = 2.0f * exps[i].position_deg * (PI_F / 180.0f);
        d.x[0][i] = 1.0f;
        d.x[1][i] = cosf(th);
        d.x[2][i] = sinf(th);
        g[i] = out->fit[i].gain_nm_per_v;
    }
    lsq_t full, reduced;
    hd_calib_lsq_solve(&d, g, &full);
    d.p = 1u;
    hd_calib_lsq_solve(&d, g, &reduced);
    out->position_amplitude_pct = NAN;
    out->position_phase_deg = NAN;
    out->position_p = NAN;
    if (full.rank < 3u || n < 4u) {
        return; /* fewer than 3 distinct positions (mod 180 deg) or no residual */
    }
    out->position_testable = 1u;
    float c = full.beta[1], s = full.beta[2], g0 = full.beta[0];
    out->position_amplitude_pct = 100.0f * sqrtf(c * c + s * s) / g0;
    out->position_phase_deg = 0.5f * atan2f(s, c) * (180.0f / PI_F);
    out->position_p = hd_calib_nested_pvalue(&reduced, &full, n);
    out->position_detected = (uint8_t)(out->position_p < t->alpha &&
                                       out->position_amplitude_pct >= t->min_detect_pct_fs);
}

static void campaign_stats(uint32_t n, hd_calib_report_t *out)
{
    float sg = 0.0f, so = 0.0f;
    out->nonlinearity_pct_fs = NAN;
    out->hysteresis_pct_fs = NAN;
    out->nonlinearity_measurable = 1u;
    out->hysteresis_measurable = 1u;
    for (uint32_t i = 0; i < n; ++i) {
        const hd_calib_fit_t *f = &out->fit[i];
        sg += f->gain_nm_per_v;
        so += f->offset_v;
        /* worst of the measurable ones (NaN compares false: skipped) */
        if (f->nonlinearity_measurable &&
            !(f->nonlinearity_pct_fs <= out->nonlinearity_pct_fs)) {
            out->nonlinearity_pct_fs = f->nonlinearity_pct_fs;
        }
        if (f->hysteresis_measurable && !(f->hysteresis_pct_fs <= out->hysteresis_pct_fs)) {
            out->hysteresis_pct_fs = f->hysteresis_pct_fs;
        }
        out->nonlinearity_measurable &= f->nonlinearity_measurable;
        out->hysteresis_measurable &= f->hysteresis_measurable;
        out->nonlinearity_detected |= f->nonlinearity_detected;
        out->hysteresis_detected |= f->hysteresis_detected;
    }
    out->gain_mean_nm_per_v = sg / (float)n;
    out->offset_mean_v = so / (float)n;
    if (n < 2u) {
        out->gain_std_nm_per_v = NAN;
        out->consistency = NAN;
        return;
    }
    float ss = 0.0f;
    for (uint32_t i = 0; i < n; ++i) {
        float dg = out->fit[i].gain_nm_per_v - out->gain_mean_nm_per_v;
        ss += dg * dg;
    }
    out->gain_std_nm_per_v = sqrtf(ss / (float)(n - 1u));
    out->consistency = out->gain_std_nm_per_v / out->gain_mean_nm_per_v;
}

static void decide(uint32_t n, const hd_calib_thresholds_t *t, hd_calib_report_t *out)
{
    uint32_t r = 0;
    uint32_t min_exp = t->min_experiments < 2u ? 2u : t->min_experiments;
    if (n < min_exp) {
        r |= HD_CALIB_REJECT_FEW_EXPERIMENTS;
    }
    /* NaN consistency (single experiment) must not pass: test the negation. */
    if (!(out->consistency <= t->max_consistency)) {
        r |= HD_CALIB_REJECT_INCONSISTENT;
    }
    /* Size limits apply only to effects that are really there (significant
     * and above the resolution floor), so noise alone never rejects. */
    for (uint32_t i = 0; i < n; ++i) {
        const hd_calib_fit_t *f = &out->fit[i];
        if (f->nonlinearity_detected && f->nonlinearity_pct_fs > t->max_nonlinearity_pct_fs) {
            r |= HD_CALIB_REJECT_NONLINEAR;
        }
        if (f->hysteresis_detected && f->hysteresis_pct_fs > t->max_hysteresis_pct_fs) {
            r |= HD_CALIB_REJECT_HYSTERESIS;
        }
    }
    if (out->position_detected && out->position_amplitude_pct > t->max_position_pct) {
        r |= HD_CALIB_REJECT_POSITION;
    }
    /* A limit that cannot be checked is not met. */
    if (!t->allow_unmeasurable && (!out->nonlinearity_measurable ||
                                   !out->hysteresis_measurable || !out->position_testable)) {
        r |= HD_CALIB_REJECT_NOT_MEASURABLE;
    }
    out->reject_reasons = r;
    out->accepted = (uint8_t)(r == 0u);
}

static int thresholds_ok(const hd_calib_thresholds_t *t)
{
    return finite_f(t->max_consistency) && finite_f(t->max_nonlinearity_pct_fs) &&
           finite_f(t->max_hysteresis_pct_fs) && finite_f(t->max_position_pct) &&
           t->alpha > 0.0f && t->alpha < 1.0f && finite_f(t->min_detect_pct_fs) &&
           t->allow_unmeasurable <= 1u;
}

int hd_calib_analyze(const hd_calib_experiment_t *exps, uint32_t n_experiments,
                     const hd_calib_thresholds_t *t, hd_calib_report_t *out)
{
    if (out == NULL) {
        return HD_CALIB_ERR_ARG;
    }
    memset(out, 0, sizeof *out);
    out->error_experiment = -1;
    out->consistency = NAN;
    out->position_amplitude_pct = NAN;
    out->position_phase_deg = NAN;
    out->position_p = NAN;
    if (exps == NULL || t == NULL || n_experiments == 0u ||
        n_experiments > HD_CALIB_MAX_EXPERIMENTS || !thresholds_ok(t)) {
        return HD_CALIB_ERR_ARG;
    }
    for (uint32_t i = 0; i < n_experiments; ++i) {
        int err = hd_calib_fit_experiment(&exps[i], t->alpha, t->min_detect_pct_fs,
                                          &out->fit[i]);
        if (err != HD_CALIB_OK) {
            out->error_experiment = (int32_t)i;
            return err;
        }
    }
    out->n_experiments = n_experiments;
    campaign_stats(n_experiments, out);
    position_test(exps, n_experiments, t, out);
    decide(n_experiments, t, out);
    return n_experiments < 2u ? HD_CALIB_ERR_SINGLE_EXPERIMENT : HD_CALIB_OK;
}

const char *hd_calib_strerror(int err)
{
    switch (err) {
    case HD_CALIB_OK: return "ok";
    case HD_CALIB_ERR_ARG: return "invalid argument (NULL, count out of range or bad thresholds)";
    case HD_CALIB_ERR_TOO_FEW_POINTS: return "fewer than two load points in an experiment";
    case HD_CALIB_ERR_LOADS_EQUAL: return "all applied torques of an experiment are equal: no slope";
    case HD_CALIB_ERR_NONFINITE: return "non-finite value (NaN or Inf) in torque, bridge output or position";
    case HD_CALIB_ERR_DIRECTION: return "direction must be load or unload";
    case HD_CALIB_ERR_SLOPE: return "bridge output does not increase with torque (reversed wiring or no signal)";
    case HD_CALIB_ERR_SINGLE_EXPERIMENT: return "a single experiment: no consistency measure (need at least two)";
    default: return "unknown error";
    }
}

const char *hd_calib_reason_str(uint32_t reason_bit)
{
    switch (reason_bit) {
    case HD_CALIB_REJECT_FEW_EXPERIMENTS: return "too few experiments";
    case HD_CALIB_REJECT_INCONSISTENT: return "gain not consistent across experiments";
    case HD_CALIB_REJECT_NONLINEAR: return "nonlinearity above limit";
    case HD_CALIB_REJECT_HYSTERESIS: return "hysteresis above limit";
    case HD_CALIB_REJECT_POSITION: return "gain depends on flexspline position";
    case HD_CALIB_REJECT_NOT_MEASURABLE:
        return "not measurable from this data (nonlinearity: >= 3 load levels; hysteresis: "
               "loading and unloading at a nonzero load; position: >= 3 positions mod 180 deg "
               "and >= 4 experiments)";
    default: return "unknown reason";
    }
}

uint32_t hd_calib_sizeof_experiment(void) { return (uint32_t)sizeof(hd_calib_experiment_t); }
uint32_t hd_calib_sizeof_report(void) { return (uint32_t)sizeof(hd_calib_report_t); }
uint32_t hd_calib_sizeof_record(void) { return (uint32_t)sizeof(hd_calib_record_t); }
