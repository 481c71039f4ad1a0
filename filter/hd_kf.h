/*
 * hd_kf: the ripple-cancelling Kalman filter of Taghirad, Helmy & Belanger
 * (1997), equations 5-10, as a float32, allocation-free library.  This
 * header holds the contracts; why each rule exists, with the measurements
 * behind it, is in docs/design/filter.md.
 *
 * Model.  The torque ripple y = T_meas - T_exp is the sum of the first
 * states of a bank of 2-state oscillators, plus, if enabled, one
 * random-walk offset state:
 *
 *   x(k) = Phi(k) x(k-1) + w(k),   y(k) = C(k) x(k) + v(k),
 *   Phi = blockdiag(R(theta_1), ..., R(theta_B), 1),
 *   R(t) = [cos t  sin t; -sin t  cos t],   C = [c_1 0 c_2 0 ... c_B 0 (1)].
 *
 * Each block is locked to one reference; its phase advance theta from the
 * previous sample to this one comes from the encoder increments passed
 * with this sample:
 *   HD_KF_LOCK_MOTOR   theta = order * d_motor_angle_rad   [order: cycles per motor rev]
 *   HD_KF_LOCK_OUTPUT  theta = order * d_output_angle_rad  [order: cycles per output rev]
 *   HD_KF_LOCK_FIXED   theta = 2 pi f ts_s                 [order field holds f in Hz]
 *
 * Step k, given sample k: y_k and the increments d_k = angle_k -
 * angle_k-1 (scalar innovation, no inverse):
 *   time update   x <- Phi(d_k) x,   P <- Phi P Phi' + Q(d_k)
 *   innovation    e = y_k - C x,  S = R + C P C',  g = P C',
 *                 F = diag(gain fractions)
 *   measurement   x <- x + F g e / S
 *                 P <- P - (F g g' + g g' F - F g g' F) / S
 * which is the Joseph form for the gain F g / S (the optimal update when
 * every fraction is 1), so P stays the exact covariance of the estimate.
 * Every rule below (freezes, motion fractions, q, rows) is decided from
 * d_k.  x after step k is the estimate AT sample k (the posterior, at the
 * angles of sample k); the outputs of step k come from the prior x(k|k-1):
 * the estimate of sample k-1 turned by sample k's own increments, a
 * prediction that never uses y_k.
 *
 * Per-block rules (docs/design/filter.md explains each):
 *   - measurement row: c = 1 + ripple_load_coeff_per_nm |T_ref| for
 *     motor-locked blocks (1 when the coefficient is 0), output_row for
 *     held output-locked blocks given a profile line when following (below),
 *     1 for the other output-locked and fixed blocks, 0 for a frozen block;
 *     the offset's entry is 1.  T_ref starts at T_exp (+ the offset when it
 *     is real torque and primed) and follows it by the motor's motion
 *     fraction: held at standstill;
 *   - held output rows (output_row_follow > 0 and output_learn_scale 0):
 *     hd_kf_profile_import keeps the imported motor blocks' states as the
 *     reference and the profile's load_nm as T_c; the growth
 *     g = sqrt(sum |x_m|^2 / sum |ref_m|^2) over them is measured on steps
 *     where every enabled motor block is at motion 1, none frozen, and turns
 *     at least HD_KF_FOLLOW_MIN_RAD, from HD_KF_FOLLOW_SETTLE_S after the
 *     import; those steps feed an exponentially weighted regression of g on
 *     |T_ref| (memory HD_KF_FOLLOW_MEMORY_S; its slope used once
 *     HD_KF_FOLLOW_MIN_WEIGHT of its weight is filled and |T_ref| has varied
 *     by more than HD_KF_FOLLOW_MIN_VAR_NM2, |T| taken within 2 standard
 *     deviations of its mean).  The growth the load explains, the
 *     regression at |T_ref| over the regression at T_c, is the target's g
 *     (lines changed at a constant load, by wear or temperature, do not
 *     move the row), times (1 + c |T_ref|) / (1 + c T_c) with a model load
 *     coefficient c (the only factor when no motor line was imported);
 *     T_c unknown (negative): the row stays 1.  The
 *     target 1 + output_row_follow (g - 1) beyond
 *     [1 / output_row_max, output_row_max] (or not a number) is refused:
 *     the bound is taken, HD_KF_STATUS_LOAD_BOUND, load_bound_count.
 *     output_row follows the target through a low-pass of
 *     HD_KF_OUTPUT_ROW_TAU_S; it is 1 with neither an imported motor line
 *     nor a model coefficient, and restarts at 1 at each import and reset.
 *     The assumption: the output lines grow by the same factor as the motor
 *     lines (one strain path;
 *     docs/design/filter.md, "Load-modulated output lines");
 *   - motion fraction m = min(1, |theta| / q_motion_ref_rad) for motor- and
 *     output-locked blocks (1 when q_motion_ref_rad is 0, and for fixed
 *     blocks); process noise per state per step = q_nm2 m, times
 *     output_learn_scale for output-locked blocks.  With
 *     q_motion_ref_profiled_rad > 0, a block given a line by
 *     hd_kf_profile_import takes that reference instead, until an import
 *     that gives it none, hd_kf_reset or its toggle (a line a profile holds
 *     learns only from motion clearly faster than the offset settles:
 *     docs/design/filter.md, "Slow motor blocks");
 *   - gain fraction: m for motor-locked blocks, output_learn_scale for
 *     output-locked blocks, 1 for fixed blocks and the offset, 0 for a frozen
 *     block;
 *   - Nyquist: a block with |theta| > nyquist_fraction * pi is frozen for the
 *     step (c = 0, gain 0, no process noise, still turned by theta); beyond
 *     HD_KF_PHASE_LOST_RAD its phase is lost and it restarts from zero with
 *     its p0, decorrelated (before the step's measurement update);
 *   - offset: primed with the first valid sample's y - ripple; with
 *     offset_jump_nm > 0 an innovation with |e| > offset_jump_nm and
 *     e^2 > 16 S adds e^2 to the offset's variance before the update
 *     (HD_KF_STATUS_OFFSET_JUMP).  An event (a load step, a spike and its
 *     return) is at most HD_KF_JUMP_BURST jumps: the gate takes no more
 *     until HD_KF_JUMP_REARM_S of steps in a row have stayed within it;
 *     each step beyond it restarts that count, and one beyond it with no
 *     jump left is HD_KF_STATUS_UNMODELLED, counted in jump_held_count (an
 *     effect the model lacks, not a load step);
 *   - transients: the blocks' states are kept at an event's first step
 *     beyond the jump gate.  An event whose innovation went beyond
 *     correction_max_nm (> 0) while the motor angle spanned less than
 *     HD_KF_EVENT_TURN_RAD is a transient: when it ends, and when the
 *     correction limit would restart the filter within it (instead of
 *     the restart), the blocks go back to those states (not their
 *     covariance; rollback_count).  A block cleared, restarted or
 *     imported during an event keeps what was written;
 *   - offset drift: with offset_drift_q_nm2 > offset_q_nm2 (an offset told
 *     to be slow because the load is known), a step beyond the jump gate
 *     (OFFSET_JUMP or UNMODELLED) says the load is not the known one: for
 *     HD_KF_DRIFT_HOLD_S from the next step (and from a (re)start) the
 *     offset's q per step is offset_drift_q_nm2 (drift_count counts those
 *     steps).  Left to the slow offset, a slowly turning block takes the
 *     load instead, a ramp of slope s as an amplitude s / omega.
 *
 * Invariants kept every step:
 *   - P (the posterior's) is stored once (packed upper triangle), so it is
 *     exactly symmetric;
 *   - each block's 2x2 covariance is positive semi-definite with its
 *     largest eigenvalue at most p_max_nm2 (so every diagonal entry is in
 *     [0, p_max], whatever the block's phase), and the offset's variance is
 *     in [0, p_max]: a block above the ceiling has its two rows and columns
 *     scaled by sqrt(p_max / lambda_max), the offset by sqrt(p_max / P_oo)
 *     (congruences: PSD kept; counted in p_ceiling_count); a block
 *     covariance that is not PSD or a negative offset variance (float32
 *     rounding) has its rows and columns zeroed (p_negative_count); either
 *     sets HD_KF_STATUS_P_CLAMPED;
 *   - a non-finite increment is taken as 0, and a non-finite or absurd
 *     sample (|T_meas - T_exp| > HD_KF_MAX_ABS_Y_NM) is not corrected
 *     (time update only); both set HD_KF_STATUS_BAD_INPUT, counted once per
 *     step in bad_input_count;
 *   - a non-finite state or covariance resets the filter (hd_kf_reset),
 *     HD_KF_STATUS_RESET, reset_count: in the step that uses it (a state
 *     that overflows in a correction is seen by the next step's prior);
 *   - the published filtered torque is always finite;
 *   - with correction_max_nm > 0, |T_meas - filtered| <= correction_max_nm:
 *     a correction beyond it is wrong (beyond any modelled line), so the
 *     step publishes the measurement itself (filtered = T_meas, ripple_nm
 *     the published correction), HD_KF_STATUS_LIMITED, counted in
 *     limit_count; once the steps at the limit outnumber those below it
 *     by HD_KF_LIMIT_RESTART_S, the filter restarts (hd_kf_reset after
 *     the step, HD_KF_STATUS_RESET, reset_count; within a transient, see
 *     above, the blocks go back to its start instead): an estimate beyond
 *     any physical ripple is wrong, and keeping it would only hold the
 *     output at the limit.
 *
 *   - run-time toggles (hd_kf_set_block_enabled) change no other state.
 *
 * Cost: hd_kf_step is O(n^2) in the configured states (a model of more than
 * 4 blocks runs at the cost of HD_KF_MAX_BLOCKS), bounded, never blocks,
 * never allocates, calls no libm (sine/cosine: hd_trig.h).  The library
 * keeps no globals: all state is in hd_kf_t.
 */
#ifndef HD_KF_H
#define HD_KF_H

#include <stdbool.h>
#include <stdint.h>

#include "hd_filter_err.h"

#ifdef __cplusplus
extern "C" {
#endif

/* Compile-time capacity.  hd_kf_t's size follows from these. */
#ifndef HD_KF_MAX_BLOCKS
#define HD_KF_MAX_BLOCKS 8
#endif
#define HD_KF_MAX_STATES (2 * HD_KF_MAX_BLOCKS + 1)
/* Blocks of integral order up to this take their frame from powers of the
 * motor or output phasor; the others turn their own. */
#define HD_KF_MAX_POWER 8
#define HD_KF_PHASORS (2 * (HD_KF_MAX_POWER + 1) + HD_KF_MAX_BLOCKS)
/* Entries of the packed upper triangle of P at capacity. */
#define HD_KF_P_ENTRIES (HD_KF_MAX_STATES * (HD_KF_MAX_STATES + 1) / 2)

/* Largest |T_meas - T_exp| the filter corrects with [N m]; beyond it (or
 * non-finite) a sample is bad input. */
#define HD_KF_MAX_ABS_Y_NM 1.0e6f

/* Largest accepted p0 / r (and output_p0 / r): float32 keeps ~7 digits of
 * the first update's p0 - (p0 - r) (docs/design/filter.md, "Priors"). */
#define HD_KF_MAX_P0_OVER_R 1.0e4f

/* Largest accepted ripple_load_coeff_per_nm [1/Nm] (c^2 P must not
 * overflow float32). */
#define HD_KF_MAX_LOAD_COEFF_PER_NM 100.0f

/* Largest accepted output_row_max: a held output line may follow the motor
 * lines to at most this times its profile's amplitude. */
#define HD_KF_MAX_OUTPUT_ROW 100.0f
/* The growth is measured while every motor block turns at least this far
 * per step (below, the offset's random walk and the motor lines share a
 * band), not in the first HD_KF_FOLLOW_SETTLE_S [s] after an import, and
 * regressed on |T_ref| with this memory [s]; the slope is used once
 * HD_KF_FOLLOW_MIN_WEIGHT of the regression's weight is filled and |T_ref|
 * varies by more than HD_KF_FOLLOW_MIN_VAR_NM2 (docs/design/filter.md,
 * "Load-modulated output lines").  The held output rows follow the target
 * through a first-order low-pass of HD_KF_OUTPUT_ROW_TAU_S [s]. */
#define HD_KF_FOLLOW_MIN_RAD 0.05f
#define HD_KF_FOLLOW_MEMORY_S 10.0f
#define HD_KF_FOLLOW_MIN_VAR_NM2 0.01f
#define HD_KF_FOLLOW_MIN_WEIGHT 0.05f
#define HD_KF_FOLLOW_SETTLE_S 0.5f
#define HD_KF_OUTPUT_ROW_TAU_S 0.01f

/* The offset-jump gate takes at most HD_KF_JUMP_BURST jumps (a step, or a
 * spike and its return), then holds until this long within it [s]. */
#define HD_KF_JUMP_BURST 2u
#define HD_KF_JUMP_REARM_S 0.2f

/* An event beyond the jump gate whose innovation went beyond
 * correction_max_nm while the motor angle spanned less than this [rad] (one
 * turn) is a transient, not a line (the rule above). */
#define HD_KF_EVENT_TURN_RAD 6.2831853f

/* Offset drift gate (offset_drift_q_nm2 > offset_q_nm2): a step beyond the
 * jump gate holds it for this long [s]. */
#define HD_KF_DRIFT_HOLD_S 1.0f

/* A filter whose steps at correction_max_nm outnumber the others by this
 * long restarts (hd_kf_reset) [s]. */
#define HD_KF_LIMIT_RESTART_S 0.1f

/* A block phase advance beyond this in one step [rad] (four turns) is an
 * encoder fault, not motion: the block restarts. */
#define HD_KF_PHASE_LOST_RAD 25.132741f

typedef enum {
    HD_KF_LOCK_MOTOR = 0,
    HD_KF_LOCK_OUTPUT = 1,
    HD_KF_LOCK_FIXED = 2,
} hd_kf_lock_t;

typedef struct {
    uint8_t lock;    /* hd_kf_lock_t */
    uint8_t enabled; /* 0: the block is configured but not part of the model */
    float order;     /* cycles per rev (MOTOR, OUTPUT) or frequency in Hz (FIXED) */
    float q_nm2;     /* process noise added per step to each of its 2 states [Nm^2] */
} hd_kf_block_config_t;

typedef struct {
    hd_kf_block_config_t blocks[HD_KF_MAX_BLOCKS];
    uint8_t block_count;           /* blocks[0, block_count) are configured */
    uint8_t offset_enabled;        /* add the random-walk offset state */
    uint8_t offset_is_sensor_error; /* 1: subtract the offset from the filtered torque
                                      (sensor drift); 0: it is real torque the
                                      expected-torque model misses, keep it */
    float offset_q_nm2;            /* offset random-walk variance per step [Nm^2] */
    float r_nm2;                   /* measurement noise variance R [Nm^2], > 0 */
    float ts_s;                    /* sample period [s] */
    float p0_nm2;                  /* initial / reset variance of motor-locked and fixed
                                      blocks and of the offset [Nm^2] */
    float output_p0_nm2;           /* initial / reset variance of output-locked blocks [Nm^2] */
    float q_motion_ref_rad;        /* > 0: motion fraction min(1, |theta| / this) scales q
                                      and motor-block gains; 0: off (the paper) */
    float p_max_nm2;               /* ceiling on covariance diagonal [Nm^2] */
    float nyquist_fraction;        /* freeze a block when |theta| > this * pi, in (0, 1] */
    float offset_jump_nm;          /* > 0: offset-jump gate threshold [Nm]; 0: off */
    float ripple_load_coeff_per_nm; /* >= 0: motor-locked rows are 1 + coeff |T_ref|;
                                      0: off; at most HD_KF_MAX_LOAD_COEFF_PER_NM */
    float output_learn_scale;      /* in [0, 1]: multiplies the gain and q of output-locked
                                      blocks (1: learn as the other blocks, the default;
                                      0: they predict and turn, but never learn) */
    float correction_max_nm;       /* > 0: a correction (T_meas minus the filtered
                                      torque) beyond +-this is not published (the step
                                      publishes T_meas), and a filter that keeps reaching
                                      it restarts; 0: off */
    float offset_drift_q_nm2;      /* > offset_q_nm2: the offset's q per step while the
                                      drift gate holds (an offset slowed for a known load,
                                      after a step beyond the jump gate); 0: gate off */
    float output_row_follow;       /* in [0, 1]: the rows of held output-locked blocks
                                      (output_learn_scale 0) follow the motor lines' growth
                                      since the profile import: 1 + this (rho - 1), rho
                                      the motor blocks' projection on their imported
                                      states; 0: off (rows 1) */
    float output_row_max;          /* with output_row_follow > 0: the envelope of that
                                      row, [1 / this, this]; in [1, HD_KF_MAX_OUTPUT_ROW] */
    float q_motion_ref_profiled_rad; /* > 0: the q_motion_ref_rad of a motor- or
                                      output-locked block that holds an imported profile
                                      line (hd_kf_profile_import; until a reset or its
                                      toggle); 0: off (q_motion_ref_rad for every block) */
} hd_kf_config_t;

/* Per-step input. */
typedef struct {
    float torque_meas_nm;       /* calibrated measured torque */
    float torque_expected_nm;   /* T_exp from hd_expected.h (or 0) */
    float d_motor_angle_rad;    /* motor angle at this sample minus at the previous one */
    float d_output_angle_rad;   /* output angle at this sample minus at the previous one */
    float torque_expected_var_nm2; /* variance of T_exp's error at this sample, added to
                                      R for this step (0: T_exp as exact as R says); a
                                      negative or non-finite value counts as 0, a larger
                                      one as HD_KF_MAX_EXPECTED_VAR_NM2 */
} hd_kf_input_t;

/* Ceiling of hd_kf_input_t.torque_expected_var_nm2: S stays finite. */
#define HD_KF_MAX_EXPECTED_VAR_NM2 1.0e12f

/* Status bits in hd_kf_output_t.status and hd_kf_t.status_sticky (names:
 * hd_kf_status_name). */
#define HD_KF_STATUS_FROZEN      (1u << 0) /* at least one block over Nyquist this step */
#define HD_KF_STATUS_BAD_INPUT   (1u << 1) /* non-finite input: correction skipped */
#define HD_KF_STATUS_RESET       (1u << 2) /* non-finite state or covariance: filter reset */
#define HD_KF_STATUS_P_CLAMPED   (1u << 3) /* covariance brought back to PSD, <= p_max */
#define HD_KF_STATUS_OFFSET_JUMP (1u << 4) /* innovation beyond the gate: offset jump */
#define HD_KF_STATUS_LIMITED     (1u << 5) /* correction beyond correction_max_nm: raw out */
#define HD_KF_STATUS_UNMODELLED  (1u << 6) /* beyond the held jump gate: an effect the
                                              model lacks (jump_held_count) */
#define HD_KF_STATUS_LOAD_BOUND  (1u << 7) /* the held output rows' target left
                                              [1 / output_row_max, output_row_max]:
                                              held at the bound (load_bound_count) */
#define HD_KF_STATUS_BITS 8u               /* bits [0, HD_KF_STATUS_BITS) are defined */

typedef struct {
    float torque_filtered_nm;  /* T_meas - ripple (- offset if sensor error) */
    float ripple_nm;           /* estimated ripple, all active unfrozen blocks */
    float offset_nm;           /* offset state (0 if disabled) */
    float innovation_nm;       /* e = y - C x (prior); 0 when not corrected */
    float innovation_var_nm2;  /* S = R + C P C' (prior, after an offset jump) */
    uint32_t frozen_mask;      /* bit i: configured block i frozen this step */
    uint32_t status;           /* HD_KF_STATUS_* for this step */
} hd_kf_output_t;

/* Per configured block (slot i = configured block i), derived from the
 * configuration (filled by hd_kf_init; enabled by hd_kf_set_block_enabled). */
typedef struct {
    uint8_t lock;        /* hd_kf_lock_t, also the index of its increment */
    uint8_t frame;       /* its frame phasor: entry of hd_kf_t.phasor_cos/sin */
    uint8_t enabled;     /* 0: held at zero (x, its rows and columns of P) */
    uint8_t reserved;
    float theta_per_unit; /* phase advance per unit of its increment: the order
                             (FIXED: 2 pi f ts per step, its increment is 1) */
    float motion_inv;    /* motion fraction = min(1, |theta| motion_inv + motion_bias) */
    float motion_bias;
    float q_nm2;         /* q, times output_learn_scale for output-locked blocks */
    float p0_nm2;
    float learn;         /* gain fraction before motion: output_learn_scale or 1 */
    float fixed_cos;     /* FIXED: its phase advance of every step, as a phasor */
    float fixed_sin;
    float full_rad;      /* MOTOR: |increment| from which its motion fraction is 1 */
    float frozen_rad;    /* MOTOR, OUTPUT: |increment| from which it is over Nyquist */
    float full_shared_rad;   /* MOTOR: full_rad at q_motion_ref_rad, and */
    float full_profiled_rad; /* at q_motion_ref_profiled_rad (built once, at init:
                                switching needs no search in the tick) */
} hd_kf_slot_t;

/* Filter state.  Treat as opaque; it is public only so it can be allocated
 * statically.  Every configured block has its place (slot i = configured
 * block i, states 2i and 2i+1, the offset last at 2 n_blocks, also when it
 * is disabled); a disabled block's (or offset's) state and its rows and
 * columns of P are held at zero, which keeps it out of every other state's
 * update (hd_kf_set_block_enabled).
 * x and p hold each block's state and covariance in the block's co-rotating
 * frame: the model's x_s = R(phi_s) x[2s..2s+1], phi_s the block's
 * accumulated phase (phasor_cos/sin[slot.frame]), so a step turns no state
 * and no covariance, only the frames (docs/design/filter.md, "Co-rotating
 * frames").  hd_kf_state and hd_kf_cov return the model's coordinates in the
 * active ordering (enabled blocks, offset last). */
typedef struct {
    hd_kf_config_t cfg;
    uint8_t n_states;                         /* active states: 2 per enabled block (+1) */
    uint8_t n_blocks;                         /* blocks in the layout: cfg.block_count */
    uint8_t offset_slot;                      /* x index of the offset: 2 n_blocks */
    uint8_t offset_primed;                    /* the offset has taken its first sample */
    uint8_t load_ref_primed;                  /* load_ref_nm has taken its first value */
    uint32_t motor_powers;                    /* bit k: the k-th power of the motor phasor is used */
    uint32_t output_powers;                   /* the same for the output phasor */
    uint32_t own_frames;                      /* bit s: slot s turns its own phasor */
    uint32_t motor_slots;                     /* bit s: slot s is an enabled motor block */
    uint32_t output_slots;                    /* ... an enabled output block */
    uint32_t output_partial_slots;            /* ... of those, learning at a scale below 1 */
    uint32_t frozen_mask;                     /* by configured block index, last step */
    float offset_q_nm2;                       /* the offset's q per step (0: disabled) */
    float nyquist_limit_rad;                  /* nyquist_fraction * pi */
    float motor_full_rad;                     /* |motor increment| in [full, frozen): every */
    float motor_frozen_rad;                   /* motor block at motion 1, none frozen */
    float output_frozen_rad;                  /* |output increment| below: none frozen */
    float q_motion_inv_rad;                   /* 1 / q_motion_ref_rad (0: off) */
    float load_ref_nm;                        /* T_ref of the load-dependent row [Nm] */
    float load_scale;                         /* 1 + k |T_ref| of the last step */
    float output_phase_hi_rad;                /* the sum of all output increments since */
    float output_phase_lo_rad;                /* init, in [-pi, pi), as hi + lo */
    uint32_t output_turns;                    /* steps since the output phasor was last
                                                 set from that sum */
    hd_kf_slot_t slot[HD_KF_MAX_BLOCKS];      /* configured block -> its step parameters */
    float phasor_cos[HD_KF_PHASORS];          /* unit phasors: [k] the motor phase (sum of */
    float phasor_sin[HD_KF_PHASORS];          /* all increments) times k, [HD_KF_MAX_POWER
                                                 + 1 + k] the output phase's, then one per
                                                 configured block that turns its own */
    float x[HD_KF_MAX_STATES];                /* blocks (in their frames), then offset */
    float p[HD_KF_P_ENTRIES];                 /* packed by 2x2 tiles, in the frames */
    uint32_t status_sticky;                   /* OR of all step statuses since init */
    uint32_t reset_count;
    uint32_t bad_input_count;
    uint32_t p_ceiling_count;                 /* blocks (or the offset) brought down to p_max */
    uint32_t p_negative_count;                /* non-PSD blocks / negative offset zeroed */
    uint32_t jump_rearm_steps;                /* HD_KF_JUMP_REARM_S in steps (at least 1) */
    uint32_t jump_hold_steps;                 /* quiet steps left until the jumps come back */
    uint32_t jump_credit;                     /* jumps the gate may still take */
    uint32_t jump_held_count;                 /* steps beyond the gate while it was held */
    float event_angle_rad;                    /* motor angle since the event began */
    float event_min_rad;                      /* its least and greatest values: the */
    float event_max_rad;                      /* span of angles the event covered */
    float event_peak_nm2;                     /* its greatest squared innovation */
    uint32_t rollback_count;                  /* short events whose learning was undone */
    float event_x[2u * HD_KF_MAX_BLOCKS];     /* the blocks' states before the event */
    uint32_t limit_restart_steps;             /* HD_KF_LIMIT_RESTART_S in steps (at least 1) */
    uint32_t limit_steps;                     /* steps at the limit less those below it */
    uint32_t limit_count;                     /* steps with the correction held */
    uint32_t drift_hold_total;                /* HD_KF_DRIFT_HOLD_S in steps */
    uint32_t drift_hold_steps;                /* steps left at offset_drift_q_nm2 */
    uint32_t drift_count;                     /* steps at offset_drift_q_nm2 */
    uint32_t output_follow;                   /* 1: held output rows follow the motor lines */
    uint32_t follow_slots;                    /* bit s: an output block given a profile line
                                                 (its row is output_row; the others' 1) */
    uint32_t load_bound_count;                /* steps with the follow target at a bound */
    float output_row;                         /* the held output blocks' row (1: as profiled) */
    float output_row_alpha;                   /* ts / HD_KF_OUTPUT_ROW_TAU_S */
    float motor_ref_inv;                      /* 1 / sum |motor_ref|^2 (0: no reference) */
    float follow_min_rad;                     /* |motor increment| from which every motor
                                                 block turns HD_KF_FOLLOW_MIN_RAD per step */
    uint32_t follow_primed;                   /* the growth's regression has a sample */
    float follow_mean_t;                      /* its exponentially weighted mean |T_ref| */
    float follow_mean_g;                      /* ... mean growth */
    float follow_var_t;                       /* ... variance of |T_ref| */
    float follow_cov_tg;                      /* ... covariance of |T_ref| and growth */
    float follow_weight;                      /* ... its filled weight, 0 to 1 */
    float motor_ref[2 * HD_KF_MAX_BLOCKS];    /* motor blocks' imported states (frames) */
    float follow_load_nm;                     /* the imported profile's load_nm (< 0: unknown) */
    uint32_t profiled_slots;                  /* bit s: slot s at q_motion_ref_profiled_rad */
    uint32_t follow_settle_steps;             /* steps left before the growth is read */
    uint32_t follow_settle_total;             /* HD_KF_FOLLOW_SETTLE_S in steps */
    float learn_load_nm;                      /* exponentially weighted |T_ref| over the steps */
    float learn_load_weight;                  /* the motor blocks learn at full motion, and
                                                 its filled weight (0 to 1): export's load_nm */
} hd_kf_t;

/* A configuration with no blocks and these defaults: R = 1 Nm^2,
 * p0 = output p0 = 0.3 Nm^2, p_max = 1e6 Nm^2, nyquist_fraction = 0.9,
 * output_learn_scale = 1, offset disabled (offset q 1e-6 Nm^2 if enabled),
 * every gate off.  Add blocks with hd_kf_config_add_block. */
void hd_kf_config_default(hd_kf_config_t *cfg, float ts_s);

/* The paper's tuning: Q = 1e3 I, R = 1, motor orders 2 and 4, plus output
 * order 1 when with_misalignment (the sixth-order model of section V). */
void hd_kf_config_paper(hd_kf_config_t *cfg, float ts_s, bool with_misalignment);

/* The project's recommended tuning (docs/design/filter.md, "Recommended tuning"):
 * motor orders 2 and 4 and output order 1, plus the offset (real torque);
 *   R = noise_nm^2;
 *   q (each oscillator state) = R (ts / ripple_settle_s)^2;
 *   q (offset) = R (ts / offset_settle_s)^2;
 *   offset jump threshold 25 x noise_nm; q_motion_ref 0.05 rad;
 *   p0 0.3 Nm^2, output-locked p0 0.01 Nm^2, both capped at
 *   HD_KF_MAX_P0_OVER_R / 2 x R, so the result passes hd_kf_config_check;
 *   output_learn_scale 1.
 * Typical: noise 0.02 Nm, ripple_settle 0.05 s, offset_settle 0.02 s. */
void hd_kf_config_recommended(hd_kf_config_t *cfg, float ts_s, float noise_nm,
                              float ripple_settle_s, float offset_settle_s);

/* Appends an enabled block; returns its index or a negative hd_kf_err_t
 * (NULL, or no room).  Values are validated by hd_kf_config_check, which
 * hd_kf_init runs. */
int hd_kf_config_add_block(hd_kf_config_t *cfg, hd_kf_lock_t lock, float order,
                           float q_nm2);

/* Validates every field; returns HD_KF_OK or the first error found. */
hd_kf_err_t hd_kf_config_check(const hd_kf_config_t *cfg);

/* Name of status bit i ("FROZEN" for bit 0, ...), NULL past the last. */
const char *hd_kf_status_name(unsigned bit);

/* Copies and checks cfg, zeroes the state, sets P = p0 I, zeroes every
 * counter.  On error the filter is left unchanged. */
hd_kf_err_t hd_kf_init(hd_kf_t *kf, const hd_kf_config_t *cfg);

/* Zeroes the state and resets P = p0 I (configuration, counters and the
 * blocks' frames kept). */
void hd_kf_reset(hd_kf_t *kf);

/* Enables or disables configured block i at run time, in O(n): the block's
 * state and its rows and columns of P are zeroed (a disabled block is
 * excluded from C, gets no gain and no process noise, so it stays at zero
 * and changes no other state); enabled, it restarts from zero with
 * covariance p0.  The other blocks keep their estimates and covariances bit
 * for bit, and their steps are the same as without the block. */
hd_kf_err_t hd_kf_set_block_enabled(hd_kf_t *kf, unsigned block, bool enabled);

/* One filter step: bounded time, O(n^2) in the configured states, never
 * blocks, never allocates. */
void hd_kf_step(hd_kf_t *kf, const hd_kf_input_t *in, hd_kf_output_t *out);

/* ---- read-out, outside the 1 kHz path ---------------------------------- */

/* Amplitude [Nm] of configured block i's estimate, sqrt(x1^2 + x2^2), at
 * zero load (the same for the next step's prior: a turn keeps it); 0 if
 * the block is disabled. */
float hd_kf_block_amplitude_nm(const hd_kf_t *kf, unsigned block);

/* Measurement-row entry c of configured block i in the last step (its
 * ripple is c x1): 1 + k |T_ref| for motor-locked blocks, 1 for the others,
 * 0 if the block was frozen or is disabled. */
float hd_kf_block_row(const hd_kf_t *kf, unsigned block);

/* Amplitude [Nm] and phase [rad] of configured block i from the current
 * state (ripple_i = A cos(phase) at the sample of the last step), at zero
 * load; both 0 if the block is
 * disabled or was frozen in the last step.  Uses libm atan2f. */
void hd_kf_block_amplitude_phase(const hd_kf_t *kf, unsigned block,
                                 float *amplitude_nm, float *phase_rad);

/* Number of active states (2 per enabled block, +1 for the offset). */
unsigned hd_kf_state_count(const hd_kf_t *kf);

/* State vector and covariance entry in the active ordering (block slots in
 * configuration order, offset last); 0 outside it.  hd_kf_cov(i, j) ==
 * hd_kf_cov(j, i) bit for bit. */
float hd_kf_state(const hd_kf_t *kf, unsigned i);
float hd_kf_cov(const hd_kf_t *kf, unsigned i, unsigned j);

/* ---- angle-referenced profiles (outside the 1 kHz path) ----------------
 *
 * A motor- or output-locked block of integer order k (1..255) models the
 * ripple as a function of its ABSOLUTE lock angle alpha (the motor angle
 * for HD_KF_LOCK_MOTOR, the output angle for HD_KF_LOCK_OUTPUT):
 *
 *   ripple(alpha) = a cos(k alpha) + b sin(k alpha)        [N m, zero load]
 *
 * and its state at alpha is x = R(k alpha) (a, b)', with R the block's
 * transition above, so x1 = ripple(alpha).  Fixed-frequency blocks and
 * blocks of non-integral order are not part of a profile.
 *
 * Which angle.  x is the estimate at the sample given to the most recent
 * hd_kf_step.  The caller passes motor_angle_rad and output_angle_rad = the
 * absolute angles, reduced to [0, 2 pi), OF THAT SAMPLE.  A filter not
 * stepped since hd_kf_init / hd_kf_reset is at the sample before the first
 * one it will be given: pass the first sample's angles minus its
 * increments (its own angles when its increments are 0, as a first
 * reading's are).  The next step turns the state by that sample's
 * increments before it predicts the sample. */
typedef struct {
    uint8_t lock;   /* HD_KF_LOCK_MOTOR or HD_KF_LOCK_OUTPUT */
    uint8_t order;  /* k: cycles per revolution of the lock angle, >= 1 */
    float a_nm;     /* ripple(alpha) = a cos(k alpha) + b sin(k alpha) */
    float b_nm;
} hd_kf_profile_line_t;

typedef struct {
    uint8_t line_count;                          /* lines[0, line_count) */
    hd_kf_profile_line_t lines[HD_KF_MAX_BLOCKS];
    float load_nm; /* |T_ref| the lines were learned at (the commissioning
                      load); negative: unknown (the held output rows then
                      do not follow the motor lines) */
} hd_kf_profile_t;

/* Writes one line per enabled motor- or output-locked block of integral
 * order 1..255, in configuration order, and load_nm: |T_ref| exponentially
 * weighted (HD_KF_FOLLOW_MEMORY_S) over the steps at which every motor
 * block learned at full motion (-1 when there was none).  Returns the number of lines, or
 * HD_KF_ERR_NULL / HD_KF_ERR_ANGLE (profile untouched). */
int hd_kf_profile_export(const hd_kf_t *kf, float motor_angle_rad, float output_angle_rad,
                         hd_kf_profile_t *profile);

/* For each line, the first enabled block of the same lock and order not
 * matched by an earlier line takes the line's ripple: its state is set from
 * (a, b) at the angle above, its covariance block to prior_var_nm2 I with
 * zero covariance to every other state.  Lines without such a block are
 * ignored.  load_nm becomes the held output rows' T_c (negative or not a
 * number: unknown).  Returns the number of lines matched, or an error with
 * the filter unchanged: HD_KF_ERR_NULL, HD_KF_ERR_ANGLE, HD_KF_ERR_PROFILE
 * (line_count > HD_KF_MAX_BLOCKS, a lock other than motor/output, order 0,
 * a non-finite a or b, load_nm above HD_KF_MAX_ABS_Y_NM, prior_var_nm2 not
 * finite or outside [0, p_max]).  With q_motion_ref_profiled_rad > 0 the
 * blocks matched take it as their motion reference, every other block
 * q_motion_ref_rad. */
int hd_kf_profile_import(hd_kf_t *kf, const hd_kf_profile_t *profile, float motor_angle_rad,
                         float output_angle_rad, float prior_var_nm2);

#ifdef __cplusplus
}
#endif

#endif /* HD_KF_H */
