/*
 * The one error vocabulary of the filter library (filter/: hd_kf, hd_track,
 * hd_expected, hd_pipeline).  Every function of the library that can fail
 * returns one of these; tools reach the names and strings through
 * hd_kf_err_name / hd_kf_err_str, never as bare numbers.
 */
#ifndef HD_FILTER_ERR_H
#define HD_FILTER_ERR_H

#ifdef __cplusplus
extern "C" {
#endif

typedef enum {
    HD_KF_OK = 0,
    HD_KF_ERR_NULL = -1,
    HD_KF_ERR_BLOCK_COUNT = -2,   /* block_count > HD_KF_MAX_BLOCKS, or no such block */
    HD_KF_ERR_LOCK = -3,          /* unknown lock kind */
    HD_KF_ERR_ORDER = -4,         /* order / frequency not finite or <= 0 */
    HD_KF_ERR_NOISE = -5,         /* q, r, p0, p_max, gates or load coefficient out of range */
    HD_KF_ERR_TS = -6,            /* ts_s not finite or <= 0 */
    HD_KF_ERR_NYQUIST = -7,       /* nyquist_fraction outside (0, 1] */
    HD_KF_ERR_FIXED_OVER_NYQUIST = -8, /* fixed-frequency block at or above fs/2 */
    HD_KF_ERR_CONDITION = -9,     /* p0 / r > HD_KF_MAX_P0_OVER_R (float32 would lose P) */
    HD_KF_ERR_LEARN_SCALE = -10,  /* output_learn_scale not finite or outside [0, 1] */
    HD_KF_ERR_PROFILE = -11,      /* profile: line count, lock, order or a value invalid */
    HD_KF_ERR_ANGLE = -12,        /* angle not finite or outside [0, 2 pi) */
    HD_KF_ERR_INPUT = -13,        /* non-finite input: ignored (hd_track_update) */
    HD_KF_ERR_CORRECTION_MAX = -14, /* correction_max_nm not finite or outside [0, 1e6] */
    HD_KF_ERR_TRACK_BANDWIDTH = -100, /* tracker bandwidth not finite, <= 0 or too high */
    HD_KF_ERR_EXPECTED_CONFIG = -101, /* expected-torque configuration invalid */
} hd_kf_err_t;

/* Human-readable description of an error code (static string; "unknown
 * error" for a value that is not one). */
const char *hd_kf_err_str(int err);

/* The enumerator's name ("HD_KF_ERR_NOISE"), or NULL for a value that is
 * not one. */
const char *hd_kf_err_name(int err);

#ifdef __cplusplus
}
#endif

#endif /* HD_FILTER_ERR_H */
