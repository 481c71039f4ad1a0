/*
 * hd_kf: the ripple-cancelling Kalman filter of Taghirad, Helmy & Belanger
 * (1997), equations 5-10, as a float32, allocation-free library.
 *
 * Model.  The torque ripple y = T_meas - T_exp is the sum of the first
 * states of a bank of 2-state harmonic oscillators (equation 6), plus, if
 * enabled, one random-walk offset state:
 *
 *   x(k+1) = Phi(k) x(k) + w(k),   y(k) = C x(k) + v(k),
 *   Phi = blockdiag(R(theta_1), ..., R(theta_B), 1),
 *   R(t) = [cos t  sin t; -sin t  cos t],   C = [1 0 1 0 ... 1 0 (1)].
 *
 * Each block is locked to one reference.  Its phase advance theta over the
 * step is taken from the encoder, never from a differentiated velocity:
 *   HD_KF_LOCK_MOTOR   theta = order * (motor angle increment)   [order: cycles per motor rev]
 *   HD_KF_LOCK_OUTPUT  theta = order * (output angle increment)  [order: cycles per output rev]
 *   HD_KF_LOCK_FIXED   theta = 2 pi f ts_s                       [order field holds f in Hz]
 * The paper's model is motor orders 2 and 4 plus output order 1
 * (misalignment; omega_3 = motor velocity / gear ratio).
 *
 * Update (prediction type, equations 8-10; scalar innovation, no inverse):
 *   e = y - C x,  S = R + C P C',  g = P C',
 *   x <- Phi (x + g e / S)                               (8 with K = Phi g / S)
 *   P <- Phi (P - g g' / S) Phi' + Q                     (10, same algebra)
 * Phi is block diagonal, so one step costs O(n^2) for n states.
 *
 * Outputs, per step (x is the prediction made before this sample arrived):
 *   ripple_nm          = sum of the oscillator first states (C x without offset)
 *   torque_filtered_nm = T_meas - ripple_nm  (- offset if it is a sensor error)
 *
 * Invariants kept every step (float32 safe for long runs):
 *   - P is exactly symmetric (only the upper triangle is computed, then mirrored);
 *   - diagonal entries stay in [0, p_max_nm2]; a diagonal above p_max is
 *     brought down by scaling its row and column (a congruence, keeps PSD);
 *   - a non-finite measurement, or |T_meas - T_exp| > HD_KF_MAX_ABS_Y_NM,
 *     skips the correction (prediction only) and is flagged BAD_INPUT; a non-finite state or covariance resets the filter, flagged.
 *
 * Slow lines: an output-locked line at low output speed (order 1 at
 * 1.5 rad/s is 0.25 Hz) is nearly collinear with the offset over any short
 * window: only their sum is observed, and whatever T_exp misses (a load, an
 * acceleration) is shared between them by their variances.  An output
 * block that starts with a large variance takes most of it and hands it
 * back over one output revolution.  So output-locked blocks have their own,
 * small, initial variance (output_p0_nm2: a prior on the misalignment
 * amplitude) and learn slowly (small q, scaled by motion); the offset takes
 * the unexplained torque.  After init or reset, the offset starts at the
 * first valid sample's y - ripple (not from zero with a huge variance,
 * which would make the first float32 downdate lose all precision).
 *
 * Slow motor blocks: below q_motion_ref_rad of phase per step a
 * motor-locked block turns too little to be told from the offset, and at
 * a cold start (blocks at their prior p0) an expected torque that misses the
 * breakaway friction was explained as a 5 N m line near its zero crossing
 * (demo: a 5.8 N m spike in the first 30 ms).  So with q_motion_ref_rad > 0
 * a motor block's Kalman gain is scaled by the same motion fraction as its
 * q, min(1, |theta| / q_motion_ref_rad): it learns as it turns.  The
 * covariance update is the Joseph form for that gain, so P stays the exact
 * covariance of the estimate (hd_kf.c, covariance_update).  Measured on
 * the benchmark joint: start-up error 1.44 -> 0.31 N m RMS over the first
 * 0.5 s (peak 5.8 -> 1.0), and every scenario equal or better.
 *
 * Offset jumps: a load step is a jump of the offset, which a random walk
 * with small q does not expect; the filter would share it with whichever
 * states are uncertain (a slow output-locked block above all) and give it
 * back over one output revolution.  With offset_jump_nm > 0, an
 * innovation with |e| > offset_jump_nm and e^2 > 16 S is taken as an offset
 * jump (the manoeuvre detection of tracking filters): e^2 is added to the
 * offset's variance before the update, so the gain sends the jump to the
 * offset.  The absolute threshold keeps small unmodelled lines, which also
 * exceed 4 sigma, from triggering it.  Flagged HD_KF_STATUS_OFFSET_JUMP.
 *
 * Load-dependent ripple: the meshing torque of a strain-wave gear grows
 * with the transmitted torque.  With ripple_load_coeff_per_nm = k > 0 the
 * measurement-row entry of every motor-locked block is c = 1 + k |T_ref|
 * instead of 1, where T_ref = T_exp + offset (the filter's own slow-torque
 * estimate before this sample; T_exp alone when the offset is a sensor
 * error).  Those states are then the ripple at zero load: a load change
 * changes the predicted ripple at once instead of being learned again by
 * every block.  Output-locked (misalignment: geometry) and fixed-frequency
 * (electrical pickup) blocks keep c = 1; scaling the slow output-locked
 * line as well made it take load steps (measured in the analysis suite).
 * T_ref is held while the motor stands still and follows T_exp + offset
 * with the same motion fraction as q (min(1, |motor increment| /
 * q_motion_ref_rad)): at standstill a motor block and the offset are one
 * constant, their split is unobservable, and a c computed from the offset
 * estimate fed that split back into itself (the double reference drifted
 * the same way: ripple error 0.2 -> 7.3 N m over 60 s still).  With c
 * taken as known before the update the model stays linear.
 *
 * Nyquist: a block whose |theta| exceeds nyquist_fraction * pi for this step
 * cannot be observed without aliasing.  It is frozen for that step: dropped
 * from C and from the ripple estimate, its gain 0 (no correction; the
 * covariance update is the Joseph form for that gain), no process noise, but
 * still turned by theta, which comes from the encoder and is exact at any
 * speed.  When theta is back under the limit the block resumes with its
 * estimate.  (It used to restart from zero with p0: on a 200 Hz log whose
 * speed jitters across the limit for 3 samples at a time, 38 restarts put a
 * 7 mN m order-4 line into the output that the data did not have.)  A phase
 * advance beyond HD_KF_PHASE_LOST_RAD in one step is no motion a joint makes
 * (an encoder fault): the block's phase is lost and it restarts from zero
 * with its p0, decorrelated.
 *
 * No heap, no VLAs, no libm in hd_kf_step (sine/cosine come from hd_trig.h,
 * one sqrtf per block for the amplitude compiles to VSQRT on Cortex-M4F).
 * The library keeps no globals: all state is in hd_kf_t.
 */
#ifndef HD_KF_H
#define HD_KF_H

#include <stdbool.h>
#include <stdint.h>

#ifdef __cplusplus
extern "C" {
#endif

/* Compile-time capacity.  hd_kf_t's size follows from these. */
#ifndef HD_KF_MAX_BLOCKS
#define HD_KF_MAX_BLOCKS 8
#endif
#define HD_KF_MAX_STATES (2 * HD_KF_MAX_BLOCKS + 1)

/* Largest |T_meas - T_exp| the filter corrects with [N m]; beyond it (or
 * non-finite) a sample is bad input.  Far above any joint's torque, far
 * below where squares overflow float32. */
#define HD_KF_MAX_ABS_Y_NM 1.0e6f

/* Largest accepted p0 / r (and output_p0 / r).  The first update subtracts
 * numbers of size p0 to leave one of size r, and float32 keeps ~7 digits;
 * collinear states (blocks at standstill vs the offset) amplify the loss.
 * Measured against the double reference: p0/r = 750 -> 3e-3 N m,
 * 2.5e4 -> 0.1 N m, 3.7e9 -> state 1e8 within 6 samples.  The paper's
 * tuning is 1e3, the recommended one 750. */
#define HD_KF_MAX_P0_OVER_R 1.0e4f

/* Largest accepted ripple_load_coeff_per_nm [1/Nm]: 100 means the ripple
 * grows 100x per N m, far beyond any gear; much larger values overflow
 * c^2 P in float32 (measured: 1e20 resets the filter every step). */
#define HD_KF_MAX_LOAD_COEFF_PER_NM 100.0f

/* A block phase advance beyond this in one step [rad] (four turns: motor
 * order 2 at 12 500 rad/s at 1 kHz) is an encoder fault, not motion: the
 * block restarts (see "Nyquist"). */
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
    float r_nm2;                   /* measurement noise variance R [Nm^2] */
    float ts_s;                    /* sample period [s] */
    float p0_nm2;                  /* initial / reset variance of oscillator states [Nm^2] */
    float output_p0_nm2;           /* initial / reset variance of output-locked blocks [Nm^2]
                                      (see "Slow lines" above) */
    float q_motion_ref_rad;        /* > 0: an angle-locked block's q is scaled by
                                      min(1, |theta| / q_motion_ref_rad), i.e. ripple
                                      changes with angle travelled, not with time, and a
                                      joint at standstill does not inflate P; 0: off (paper) */
    float p_max_nm2;               /* ceiling on covariance diagonal [Nm^2] */
    float nyquist_fraction;        /* freeze a block when |theta| > this * pi, in (0, 1] */
    float offset_jump_nm;          /* > 0: an innovation larger than this [Nm] (and
                                      than 4 sigma) is a jump of the offset (see
                                      below); 0: off */
    float ripple_load_coeff_per_nm; /* >= 0: motor-locked lines scale with
                                      1 + coeff |T| (see "Load-dependent ripple");
                                      0: off (the paper's constant amplitudes);
                                      at most HD_KF_MAX_LOAD_COEFF_PER_NM */
} hd_kf_config_t;

/* Per-step input. */
typedef struct {
    float torque_meas_nm;       /* calibrated measured torque */
    float torque_expected_nm;   /* T_exp from hd_expected.h (or 0) */
    float d_motor_angle_rad;    /* motor (wave generator) angle increment over the step */
    float d_output_angle_rad;   /* output angle increment over the step */
} hd_kf_input_t;

/* Status bits in hd_kf_output_t.status and hd_kf_t.status_sticky. */
#define HD_KF_STATUS_FROZEN      (1u << 0) /* at least one block over Nyquist this step */
#define HD_KF_STATUS_BAD_INPUT   (1u << 1) /* non-finite input: correction skipped */
#define HD_KF_STATUS_RESET       (1u << 2) /* non-finite state or covariance: filter reset */
#define HD_KF_STATUS_P_CLAMPED   (1u << 3) /* a covariance diagonal hit p_max */
#define HD_KF_STATUS_OFFSET_JUMP (1u << 4) /* innovation beyond the gate: offset jump */

typedef struct {
    float torque_filtered_nm;  /* T_meas - ripple (- offset if sensor error) */
    float ripple_nm;           /* estimated ripple, all active unfrozen blocks */
    float offset_nm;           /* offset state (0 if disabled) */
    float innovation_nm;       /* e = y - C x (prior) */
    float innovation_var_nm2;  /* S = R + C P C' (prior) */
    float amplitude_nm[HD_KF_MAX_BLOCKS]; /* per configured block, at the present load
                                             (x c, see "Load-dependent ripple");
                                             0 if disabled/frozen */
    uint32_t frozen_mask;      /* bit i: block i frozen this step */
    uint32_t status;           /* HD_KF_STATUS_* for this step */
} hd_kf_output_t;

/* Filter state.  Treat as opaque; it is public only so it can be allocated
 * statically. */
typedef struct {
    hd_kf_config_t cfg;
    uint8_t n_states;                         /* active states */
    uint8_t active_blocks;                    /* number of enabled blocks */
    uint8_t block_index[HD_KF_MAX_BLOCKS];    /* active slot -> configured block */
    uint8_t offset_slot;                      /* state index of the offset, if enabled */
    uint32_t frozen_mask;                     /* by configured block index */
    uint8_t offset_primed;                    /* the offset has taken its first sample */
    uint8_t load_ref_primed;                  /* load_ref_nm has taken its first value */
    float load_ref_nm;                        /* T_ref of "Load-dependent ripple" [Nm] */
    float x[HD_KF_MAX_STATES];
    float p[HD_KF_MAX_STATES][HD_KF_MAX_STATES];
    uint32_t status_sticky;                   /* OR of all step statuses since init */
    uint32_t reset_count;
    uint32_t bad_input_count;
} hd_kf_t;

/* Errors from hd_kf_config_check / hd_kf_init. */
typedef enum {
    HD_KF_OK = 0,
    HD_KF_ERR_NULL = -1,
    HD_KF_ERR_BLOCK_COUNT = -2,   /* block_count > HD_KF_MAX_BLOCKS */
    HD_KF_ERR_LOCK = -3,          /* unknown lock kind */
    HD_KF_ERR_ORDER = -4,         /* order / frequency not finite or <= 0 */
    HD_KF_ERR_NOISE = -5,         /* q, r, p0, p_max not finite, negative, or r <= 0 */
    HD_KF_ERR_TS = -6,            /* ts_s not finite or <= 0 */
    HD_KF_ERR_NYQUIST = -7,       /* nyquist_fraction outside (0, 1] */
    HD_KF_ERR_FIXED_OVER_NYQUIST = -8, /* fixed-frequency block at or above fs/2 */
    HD_KF_ERR_CONDITION = -9,     /* p0 / r > HD_KF_MAX_P0_OVER_R (float32 would lose P) */
} hd_kf_err_t;

/* A configuration with no blocks and these defaults: R = 1 Nm^2,
 * p0 = output p0 = 0.3 Nm^2 (an amplitude prior, see HD_KF_MAX_P0_OVER_R), p_max = 1e6 Nm^2, nyquist_fraction = 0.9, offset disabled
 * (offset q 1e-6 Nm^2 if enabled).  Add blocks with hd_kf_config_add_block. */
void hd_kf_config_default(hd_kf_config_t *cfg, float ts_s);

/* The paper's tuning: Q = 1e3 I, R = 1, motor orders 2 and 4, plus output
 * order 1 when with_misalignment (the sixth-order model of section V). */
void hd_kf_config_paper(hd_kf_config_t *cfg, float ts_s, bool with_misalignment);

/* The project's recommended tuning (see README, "Tuning"): motor orders 2
 * and 4 and output order 1, plus the offset state (kept as real torque).
 *   R = noise_nm^2 (white sensor noise only: the offset state, not R, takes
 *       what T_exp misses, so the filter need not follow T_exp);
 *   q (each oscillator state) = R (ts / ripple_settle_s)^2, so a block's
 *       amplitude/phase estimate settles in ~ripple_settle_s at full speed
 *       (q is scaled by motion, so output-locked blocks, whose phase moves
 *       N times slower, get correspondingly less);
 *   q (offset) = R (ts / offset_settle_s)^2.
 *   offset jump threshold 25 x noise_nm (0.5 Nm for 0.02 Nm noise);
 *   p0 0.3 Nm^2 (the default: a prior on ripple amplitude that keeps P well
 *   conditioned in float32), output-locked p0 0.01 Nm^2, q_motion_ref 0.05 rad;
 *   both p0 are capped at HD_KF_MAX_P0_OVER_R / 2 x R, so the result always
 *   passes hd_kf_config_check (noise below ~8 mN m lowers them).
 * Typical: noise 0.02 Nm, ripple_settle 0.05 s, offset_settle 0.02 s.
 * The offset settle time trades load tracking against learning the slow
 * output-locked line: the offset's bandwidth (~1 / (2 pi settle)) must stay
 * well above the load's changes, but every bit of it hides the 0.2-0.3 Hz
 * misalignment line from its block.  Measured on the benchmark joint
 * (docs/bench.md): 5 ms left 86 mN m at 156 rad/s (floor 20), 20 ms 24;
 * slower still helps constant load a little and loses on ramps and slow
 * load changes.  Load steps are the jump gate's business, not the settle
 * time's. */
void hd_kf_config_recommended(hd_kf_config_t *cfg, float ts_s, float noise_nm,
                              float ripple_settle_s, float offset_settle_s);

/* Appends an enabled block; returns its index or a negative hd_kf_err_t
 * (NULL, or no room).  Values are validated by hd_kf_config_check, which
 * hd_kf_init runs. */
int hd_kf_config_add_block(hd_kf_config_t *cfg, hd_kf_lock_t lock, float order,
                           float q_nm2);

/* Validates every field; returns HD_KF_OK or the first error found. */
hd_kf_err_t hd_kf_config_check(const hd_kf_config_t *cfg);

/* Human-readable name of an error code (static string). */
const char *hd_kf_err_str(int err);

/* Copies and checks cfg, zeroes the state, sets P = p0 I.  On error the
 * filter is left unchanged. */
hd_kf_err_t hd_kf_init(hd_kf_t *kf, const hd_kf_config_t *cfg);

/* Zeroes the state and resets P = p0 I (configuration kept). */
void hd_kf_reset(hd_kf_t *kf);

/* Enables or disables configured block i at run time.  The block restarts
 * from zero with covariance p0; other blocks keep their estimates. */
hd_kf_err_t hd_kf_set_block_enabled(hd_kf_t *kf, unsigned block, bool enabled);

/* One filter step: bounded time, O(n^2), never blocks, never allocates. */
void hd_kf_step(hd_kf_t *kf, const hd_kf_input_t *in, hd_kf_output_t *out);

/* Amplitude [Nm] and phase [rad] of configured block i from the current
 * state (phase of the first state's oscillation: ripple_i = A cos(phase) ),
 * at zero load when ripple_load_coeff_per_nm > 0.
 * Uses libm atan2f: call it outside the 1 kHz path. */
void hd_kf_block_amplitude_phase(const hd_kf_t *kf, unsigned block,
                                 float *amplitude_nm, float *phase_rad);

/* Number of active states (2 per enabled block, +1 for the offset). */
unsigned hd_kf_state_count(const hd_kf_t *kf);

/* Read access for tests and tools: state vector and covariance entry in the
 * active ordering (block slots in configuration order, offset last). */
float hd_kf_state(const hd_kf_t *kf, unsigned i);
float hd_kf_cov(const hd_kf_t *kf, unsigned i, unsigned j);

#ifdef __cplusplus
}
#endif

#endif /* HD_KF_H */
