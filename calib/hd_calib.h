/*
 * hd_calib: static calibration of the built-in torque sensor (Taghirad 1997,
 * section III).  The wave generator is locked, known torques are applied
 * with an arm and weights, loading and unloading, in both directions, at
 * several flexspline positions, over low and full range.
 *
 * Per experiment: least-squares line bridge_v = offset_v + torque_nm/gain,
 * i.e. the bridge voltage (the noisy quantity) regressed on the applied
 * torque (known exactly), with standard errors; nonlinearity; hysteresis.
 * Across experiments: mean gain, consistency = sample std / mean of the
 * per-experiment gains (Table I: 6.60 N m/V, 2 %), dependence of the gain on
 * flexspline position (order-2 harmonic, F-test), accept/reject with reasons.
 *
 * Pure library: no heap (fixed-size arrays), no I/O, no globals, float32.
 * Uses sqrtf/expf/logf/lgammaf (libm) -- never called from the 1 kHz path.
 */
#ifndef HD_CALIB_H
#define HD_CALIB_H

#include <stdint.h>

#ifdef __cplusplus
extern "C" {
#endif

#define HD_CALIB_MAX_POINTS 64u       /* load points per experiment */
#define HD_CALIB_MAX_EXPERIMENTS 32u

#define HD_CALIB_DIR_LOAD 0u          /* |torque| increasing */
#define HD_CALIB_DIR_UNLOAD 1u        /* |torque| decreasing */

/* Error codes (0 = ok). */
#define HD_CALIB_OK 0
#define HD_CALIB_ERR_ARG (-1)            /* NULL pointer or count out of range */
#define HD_CALIB_ERR_TOO_FEW_POINTS (-2) /* fewer than two load points */
#define HD_CALIB_ERR_LOADS_EQUAL (-3)    /* all applied torques equal: no slope */
#define HD_CALIB_ERR_NONFINITE (-4)      /* NaN/Inf torque, voltage or position */
#define HD_CALIB_ERR_DIRECTION (-5)      /* direction not LOAD/UNLOAD */
#define HD_CALIB_ERR_SLOPE (-6)          /* bridge output does not rise with torque */
#define HD_CALIB_ERR_SINGLE_EXPERIMENT (-7) /* one experiment: no consistency measure */

typedef struct {
    uint32_t n_points;
    float position_deg;                        /* flexspline position of this experiment */
    float torque_nm[HD_CALIB_MAX_POINTS];      /* applied torque */
    float bridge_v[HD_CALIB_MAX_POINTS];       /* amplified bridge output */
    uint8_t direction[HD_CALIB_MAX_POINTS];    /* HD_CALIB_DIR_* */
} hd_calib_experiment_t;

typedef struct {
    uint32_t n_points;
    float position_deg;
    float full_scale_nm;          /* max |applied torque| of this experiment */
    float gain_nm_per_v;          /* torque = gain * (bridge_v - offset_v) */
    float gain_se_nm_per_v;       /* standard error (NaN if n_points < 3) */
    float offset_v;
    float offset_se_v;
    float residual_rms_v;         /* rms residual of the straight line */
    /* Nonlinearity: largest deviation of the per-level mean (midpoint of the
     * loading and unloading branches) from the fitted line, % of full scale.
     * Measurable with >= 3 distinct load levels and residual degrees of
     * freedom for its F-test; otherwise NaN (a line through two levels fits
     * them exactly: "0 %" would be a claim the data cannot make). */
    float nonlinearity_pct_fs;
    float nonlinearity_p;         /* p-value of the x^2,x^3 terms (NaN: not measurable) */
    /* Hysteresis: largest |unloading - loading| at the same applied torque,
     * % of full scale.  Measurable when a nonzero load level was read in
     * both directions (and its F-test has degrees of freedom); otherwise NaN. */
    float hysteresis_pct_fs;
    float hysteresis_p;           /* p-value of the branch term (NaN: not measurable) */
    uint8_t nonlinearity_detected; /* p < alpha and size >= min_detect_pct_fs */
    uint8_t hysteresis_detected;
    uint8_t nonlinearity_measurable;
    uint8_t hysteresis_measurable;
} hd_calib_fit_t;

typedef struct {
    float max_consistency;          /* fraction; default 0.03 */
    float max_nonlinearity_pct_fs;  /* default 1.0 */
    float max_hysteresis_pct_fs;    /* default 1.0 */
    float max_position_pct;         /* amplitude of gain vs position, % of mean; default 2.0 */
    float alpha;                    /* significance level of every test; default 0.001 */
    float min_detect_pct_fs;        /* resolution floor for a detection; default 0.02 */
    uint32_t min_experiments;       /* default 2 (>= 2 always) */
    /* 0 (default): a campaign whose nonlinearity, hysteresis (in any
     * experiment) or position dependence cannot be measured is rejected
     * (NOT_MEASURABLE); 1: accepted on the measures it has. */
    uint32_t allow_unmeasurable;
} hd_calib_thresholds_t;

/* Reject reasons (bitmask in hd_calib_report_t.reject_reasons). */
#define HD_CALIB_REJECT_FEW_EXPERIMENTS 0x01u
#define HD_CALIB_REJECT_INCONSISTENT 0x02u
#define HD_CALIB_REJECT_NONLINEAR 0x04u
#define HD_CALIB_REJECT_HYSTERESIS 0x08u
#define HD_CALIB_REJECT_POSITION 0x10u
#define HD_CALIB_REJECT_NOT_MEASURABLE 0x20u

typedef struct {
    uint32_t n_experiments;
    hd_calib_fit_t fit[HD_CALIB_MAX_EXPERIMENTS];
    float gain_mean_nm_per_v;       /* mean of per-experiment gains */
    float gain_std_nm_per_v;        /* sample standard deviation (n-1) */
    float consistency;              /* gain_std / gain_mean (fraction) */
    float offset_mean_v;
    float nonlinearity_pct_fs;      /* worst measurable experiment (NaN: none) */
    float hysteresis_pct_fs;        /* worst measurable experiment (NaN: none) */
    uint8_t nonlinearity_detected;  /* in any experiment */
    uint8_t hysteresis_detected;
    uint8_t nonlinearity_measurable; /* in every experiment */
    uint8_t hysteresis_measurable;   /* in every experiment */
    /* gain(theta) = g0 (1 + a cos(2 theta - phase)): order 2 because the
     * elliptical wave generator is two-fold symmetric. */
    uint8_t position_testable;      /* >= 3 distinct positions (mod 180 deg) and >= 4 experiments */
    uint8_t position_detected;      /* p < alpha and amplitude >= min_detect_pct_fs */
    float position_amplitude_pct;   /* a, % of g0 (NaN if not testable) */
    float position_phase_deg;       /* phase/2 in flexspline degrees */
    float position_p;               /* F-test p-value (NaN if not testable) */
    uint8_t accepted;
    uint32_t reject_reasons;        /* HD_CALIB_REJECT_* */
    int32_t error_experiment;       /* index of the experiment that caused an error, or -1 */
} hd_calib_report_t;

void hd_calib_thresholds_default(hd_calib_thresholds_t *t);

/* Fits one experiment.  alpha / min_detect_pct_fs as in the thresholds. */
int hd_calib_fit_experiment(const hd_calib_experiment_t *e, float alpha,
                            float min_detect_pct_fs, hd_calib_fit_t *out);

/* Fits every experiment and the campaign measures.  Returns HD_CALIB_OK or
 * an error; with HD_CALIB_ERR_SINGLE_EXPERIMENT the fit of the single
 * experiment is still filled in (consistency NaN, not accepted). */
int hd_calib_analyze(const hd_calib_experiment_t *exps, uint32_t n_experiments,
                     const hd_calib_thresholds_t *t, hd_calib_report_t *out);

/* Upper-tail p-value of an F(q, df) statistic (regularized incomplete beta). */
float hd_calib_f_pvalue(float f, float q, float df);

/* Static strings; never NULL. */
const char *hd_calib_strerror(int err);
const char *hd_calib_reason_str(uint32_t reason_bit);

/* sizeof, for ctypes layout checks. */
uint32_t hd_calib_sizeof_experiment(void);
uint32_t hd_calib_sizeof_report(void);
uint32_t hd_calib_sizeof_record(void);

#ifdef __cplusplus
}
#endif

#endif /* HD_CALIB_H */
