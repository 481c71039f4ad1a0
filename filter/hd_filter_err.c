/* The filter library's error vocabulary: see hd_filter_err.h. */
#include "hd_filter_err.h"

#include <stddef.h>

typedef struct {
    int code;
    const char *name;
    const char *text;
} err_entry_t;

#define ERR(code, text) {code, #code, text}
static const err_entry_t ERRORS[] = {
    ERR(HD_KF_OK, "ok"),
    ERR(HD_KF_ERR_NULL, "null pointer"),
    ERR(HD_KF_ERR_BLOCK_COUNT, "too many blocks (HD_KF_MAX_BLOCKS), or no such block"),
    ERR(HD_KF_ERR_LOCK, "unknown block lock kind"),
    ERR(HD_KF_ERR_ORDER, "block order/frequency must be finite and > 0"),
    ERR(HD_KF_ERR_NOISE, "q, r, p0, p_max, gates and load coefficient must be finite, "
                         "q >= 0, r > 0, p0 <= p_max, load coefficient <= "
                         "HD_KF_MAX_LOAD_COEFF_PER_NM"),
    ERR(HD_KF_ERR_TS, "sample period must be finite and > 0"),
    ERR(HD_KF_ERR_NYQUIST, "nyquist_fraction must be in (0, 1]"),
    ERR(HD_KF_ERR_FIXED_OVER_NYQUIST, "fixed-frequency block at or above fs/2"),
    ERR(HD_KF_ERR_CONDITION, "p0 / r above HD_KF_MAX_P0_OVER_R: float32 would lose the "
                             "covariance"),
    ERR(HD_KF_ERR_LEARN_SCALE, "output_learn_scale must be finite and in [0, 1]"),
    ERR(HD_KF_ERR_PROFILE, "profile: too many lines, a lock that is not motor/output, "
                           "order 0, a non-finite coefficient or a prior variance outside "
                           "[0, p_max]"),
    ERR(HD_KF_ERR_ANGLE, "angle must be finite and in [0, 2 pi)"),
    ERR(HD_KF_ERR_INPUT, "non-finite input (ignored)"),
    ERR(HD_KF_ERR_CORRECTION_MAX, "correction_max_nm must be finite and in [0, "
                                  "HD_KF_MAX_ABS_Y_NM]"),
    ERR(HD_KF_ERR_TRACK_BANDWIDTH, "bad tracker bandwidth for this sample rate "
                                   "(finite, > 0, 2 pi bandwidth ts <= 0.5)"),
    ERR(HD_KF_ERR_EXPECTED_CONFIG, "bad expected-torque configuration (finite, J, b, Fc >= 0, "
                                   "v_eps > 0)"),
};
#undef ERR

static const err_entry_t *find(int err)
{
    for (size_t i = 0; i < sizeof ERRORS / sizeof ERRORS[0]; i++) {
        if (ERRORS[i].code == err) {
            return &ERRORS[i];
        }
    }
    return NULL;
}

const char *hd_kf_err_str(int err)
{
    const err_entry_t *e = find(err);
    return e != NULL ? e->text : "unknown error";
}

const char *hd_kf_err_name(int err)
{
    const err_entry_t *e = find(err);
    return e != NULL ? e->name : NULL;
}
