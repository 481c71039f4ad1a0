/*
 * ref_kf_dense: an independent double-precision DENSE reference of the
 * ripple Kalman filter of Taghirad, Helmy & Belanger (1997), written for
 * clarity rather than speed from the contract in filter/hd_kf.h.  Test-only
 * code: uses double and libm, never the code under test (only its public
 * types).
 *
 * It implements the behaviour documented in filter/hd_kf.h:
 *   - blocks locked to the motor angle, the output angle or a fixed frequency,
 *     theta = order * increment (or 2 pi f ts), rotation R(theta) per block;
 *   - optional random-walk offset state (Phi = 1, C = 1);
 *   - step k: the time update by sample k's own increments (x = Phi x,
 *     P = Phi P Phi' + Q), the outputs (ripple, filtered torque, innovation,
 *     S) from that prior, then the measurement update with y_k (gain
 *     K = F P C' / S, Joseph covariance); x after the step is the estimate
 *     at sample k;
 *   - Nyquist freeze: a block with |theta| > nyquist_fraction * pi is dropped
 *     from C and from the ripple, gets gain 0 and no process noise, and is
 *     still turned by Phi (its estimate is held, not reset); beyond
 *     HD_KF_PHASE_LOST_RAD its phase is lost: state 0, covariance p0 I,
 *     decorrelated from the rest, before the update;
 *   - gain fractions (a suboptimal gain F K with the Joseph covariance
 *     update): a motor-locked block's is min(1, |theta| / q_motion_ref_rad)
 *     (1 when off), an output-locked block's is cfg.output_learn_scale,
 *     which also multiplies its q;
 *   - covariance ceiling p_max by congruence scaling: a block whose 2x2
 *     covariance has its largest eigenvalue above p_max has both its rows
 *     and columns scaled by sqrt(p_max / lambda_max); the offset by
 *     sqrt(p_max / P_oo);
 *   - angle-referenced profiles: ref_kf_profile_export / _import, written
 *     from the definition in hd_kf.h (ripple(alpha) = a cos k alpha +
 *     b sin k alpha, alpha = the lock angle of the sample the state is at:
 *     the sample of the last step, the caller's angle);
 *   - a non-finite measurement skips the correction (prediction only);
 *   - run-time block toggles: ref_kf_set_block_enabled below;
 *   - load-dependent ripple (cfg.ripple_load_coeff_per_nm = k, 0 by default,
 *     so callers that never set it get the paper's C): the C entry of the
 *     first state of every unfrozen MOTOR-locked block is
 *       c = 1 + k |T_ref|,  T_ref = T_exp + offset (prior, once primed)
 *     with the offset only when it is enabled and kept as real torque
 *     (not offset_is_sensor_error), T_exp alone otherwise; output-locked and
 *     fixed blocks keep c = 1.  Computed here in double from that
 *     definition; amplitude_nm[] is c times the state amplitude.
 *     Set it in the config before ref_kf_init, or later in r->cfg.
 */
#ifndef REF_KF_DENSE_H
#define REF_KF_DENSE_H

#include <stdint.h>

#include "hd_kf.h"

#define REF_KF_MAX_N HD_KF_MAX_STATES

typedef struct {
    hd_kf_config_t cfg;
    int n;                            /* active states */
    int nb;                           /* active (enabled) blocks */
    int block_of_slot[HD_KF_MAX_BLOCKS]; /* slot -> configured block */
    int held[HD_KF_MAX_BLOCKS];       /* slot disabled at run time: kept, held */
    int offset_slot;                  /* -1 if no offset state */
    double x[REF_KF_MAX_N];
    double P[REF_KF_MAX_N][REF_KF_MAX_N];
    /* The offset-jump test is a threshold: float and double can fall on
     * either side of it when the innovation is within rounding of it.  -1:
     * decide here; 0/1: follow the filter under test (the caller checks
     * jump_margin_rel to see that a disagreement was only rounding). */
    int jump_override;
    int jump_rearm;    /* HD_KF_JUMP_REARM_S in steps (hd_kf.h) */
    int jump_hold;     /* quiet steps left until the jumps come back */
    int jump_credit;   /* jumps the gate may still take */
    int offset_primed; /* the offset starts at the first valid y - ripple */
    int load_ref_primed; /* T_ref of the load-dependent ripple has its first value */
    double load_ref;     /* T_ref [Nm], held at standstill (hd_kf.h) */
} ref_kf_t;

typedef struct {
    double torque_filtered_nm;
    double ripple_nm;
    double offset_nm;
    double innovation_nm;
    double innovation_var_nm2;
    uint32_t frozen_mask; /* by configured block index */
    uint32_t status;      /* HD_KF_STATUS_* bits this reference can raise */
    int jump_own_decision; /* what this reference decided by itself */
    double jump_margin_rel; /* relative distance of the innovation from the threshold */
    double load_scale;      /* 1 + k |T_ref| used this step (1 when k = 0) */
    double amplitude_nm[HD_KF_MAX_BLOCKS]; /* per configured block, prior, x its C entry;
                                              0 if disabled or frozen */
} ref_kf_output_t;

/* Copies cfg (assumed valid), x = 0, P = p0 I. */
void ref_kf_init(ref_kf_t *r, const hd_kf_config_t *cfg);

/* One step with a full dense Phi: time update by in's increments, then the
 * measurement update with in's sample (hd_kf.h). */
void ref_kf_step(ref_kf_t *r, const hd_kf_input_t *in, ref_kf_output_t *out);

/* The filter as it was before it turned by the sample's own increments
 * (the paper's prediction form, equations 8-10): the measurement update of
 * in's sample first, then the time update by the increments passed with
 * it (every rule decided from them), the ceiling on the prior.  x after the
 * step is the prediction for the next sample.  Fed the NEXT sample's
 * increments, it is ref_kf_step at the same sample wherever no rule's
 * decision changes between the two increments. */
void ref_kf_step_update_first(ref_kf_t *r, const hd_kf_input_t *in, ref_kf_output_t *out);

/* Run-time enable/disable of configured block b (hd_kf.h): disabled, a
 * block keeps its place and is held like a block over Nyquist (no row in C,
 * gain 0, no process noise, still turned by Phi; not reported as frozen);
 * enabled, it restarts from zero with its p0, its rows and columns of P
 * zeroed; a block not in the model (disabled at init) is inserted so, in
 * configuration order.  Other states are untouched. */
void ref_kf_set_block_enabled(ref_kf_t *r, int b, int enabled);

/* Index in x / P of active state i (enabled blocks' states in
 * configuration order, the offset last), or -1. */
int ref_kf_active_index(const ref_kf_t *r, int i);

/* Number of active states. */
int ref_kf_active_count(const ref_kf_t *r);

/* Profile of every enabled motor/output block of integral order (1..255),
 * in configuration order: lock[i], order[i], a[i], b[i]; returns the count.
 * Angles: those of the sample of the last step, as in hd_kf.h. */
int ref_kf_profile_export(const ref_kf_t *r, double motor_angle_rad, double output_angle_rad,
                          int lock[], int order[], double a[], double b[]);

/* Line i sets the first unmatched enabled block of that lock and order:
 * state from (a, b), covariance var I, decorrelated.  Returns matches. */
int ref_kf_profile_import(ref_kf_t *r, int lines, const int lock[], const int order[],
                          const double a[], const double b[], double motor_angle_rad,
                          double output_angle_rad, double var_nm2);

#endif /* REF_KF_DENSE_H */
