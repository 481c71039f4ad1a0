/*
 * hd_ctrl: the joint controller's law, one step per tick (issue 23).
 *
 * Pure: no I/O, no HAL, no globals, no heap; float32, bounded time, no libm.
 * The firmware hands it the pipeline's output (filtered and raw flexspline
 * torque, output angle and velocity) and a setpoint; it returns the motor
 * q-axis current to command and whether the drive is enabled.
 *
 * Modes (a setpoint's mode; the step may run a safer one, see below):
 *   STOP         drive disabled, current 0, the torque loop's state cleared.
 *   DAMP         tau_ref = -damp v, open loop through the torque constant
 *                (no torque feedback: DAMP is the fallback when the gauge fails).
 *   TORQUE       tau_ref = the setpoint's torque, velocity-limited (ODrive's
 *                rule: tau within vel_gain (+-v_lim - v)).
 *   IMPEDANCE    tau_ref = kp (q_d - q) + kd (v_d - v) + tau_ff.
 *   ZERO_TORQUE  tau_ref = 0: the loop cancels what the drive train resists.
 * TORQUE, IMPEDANCE and ZERO_TORQUE track tau_ref with the torque loop:
 *   e     = tau_ref - tau_fb
 *   u     = ff tau_ref + kp_t e + I - kd_t d(tau_fb)/dt + friction_nm sat(v / v_eps)
 *           + friction_rest_nm sat(r / r_eps) max(0, 1 - |v| / v_eps)
 *                         (joint N m; the rate is the backward difference of the
 *                         feedback over one tick: it damps the flexspline's mode;
 *                         r the rate of TORQUE's torque or IMPEDANCE's tau_ff
 *                         over one tick (a stream slower than the tick gives
 *                         pulses on its updates; 0 in the other modes): at rest
 *                         the motor moves only by the flexspline's windup, in
 *                         the direction the torque is asked to move, and its
 *                         static friction holds a loop of a few Hz there
 *                         (docs/decisions/control-bandwidth.md))
 *   I    += ki ts e       only while u is not saturated in e's direction
 *                         (conditional integration: the anti-windup), and
 *                         |I| <= integral_limit_nm: the integral is there for
 *                         the drive train's friction; unbounded it also winds
 *                         up on the torque that accelerates a free output before
 *                         an impact and on the feedback's drift while a stiff
 *                         contact holds the motor still: a limit cycle at a wall
 *                         (docs/results/control.md, "Contact");
 *                         ki = ki_t, but in IMPEDANCE with 0 < kp <
 *                         integral_stiffness_nm_rad ki = ki_t sqrt(kp /
 *                         integral_stiffness_nm_rad): the integral's corner
 *                         follows the rendered mass-spring's frequency
 *                         sqrt(kp / J), kept below it, or the pushed output
 *                         hunts (docs/results/control.md, "Rendered stiffness")
 *   i_q   = u / (N kt)
 * A PI on the torque error with the setpoint fed forward: the structure of
 * the torque controllers of Taghirad & Belanger's refs [5], [10] and the
 * torque loop of Albu-Schaeffer, Ott et al. (2007), whose rate term on the
 * torque kd_t is here too, without its motor-inertia scaling (docs/results/control.md).
 * Feedback source (tau_fb): the filtered torque, the raw gauge torque, a
 * low-pass of the raw torque (corner lowpass_hz; lowpass_order 1: first
 * order, backward Euler; 2 or 4: Butterworth, bilinear with the corner
 * pre-warped, as cascaded biquads), or none: then u = tau_ref + friction,
 * open loop through kt.
 * Order notches (notch_mask, bit k-1 = order k of the motor angle): the raw
 * torque passes notches at k N |v| before RAW or LOWPASS feedback uses it,
 * tracking the speed (motor speed taken as N times the output speed);
 * -3 dB width notch_width_hz, unity gain at DC.  A notch whose frequency is
 * below notch_width_hz or above 0.45 / ts passes the torque unchanged (a
 * notch at DC would remove the torque itself; above, it would alias).
 * Narrowed filtered torque (HD_CTRL_FB_NARROW): the raw torque minus a
 * narrowband copy of the filter's artifact estimate a = raw - filtered
 * (hd_artifact.h: one phasor per motor order of artifact_mask, locked to the
 * motor angle, following its line through a low-pass of corner
 * artifact_hz, plus a slow term):
 *   tau_fb = filtered + m (a - a_hat)
 * The filter's ripple states act on the feedback as notches a few Hz wide
 * at the motor orders, which take the real torque there with the artifact;
 * a_hat removes only what stays locked to the angle for about
 * 1 / (2 pi artifact_hz): notches 2 artifact_hz wide.  m, the motion
 * fraction, fades the narrowing in as the lowest line's frequency
 * k_min N |v| / (2 pi) goes from 4 to 8 artifact_hz (with no orders, k_min
 * 1): below, the angle barely turns in the tracker's time, the phasors are
 * held and the feedback is the filtered torque (a standstill, a reversal).
 * Without a valid motor angle m = 0.  The firmware derives artifact_mask
 * from the filter's enabled motor-locked blocks of integral order 1..8.
 * Benchmarks compare these feedbacks (docs/results/control.md).
 *
 * Limits, applied last so no path exceeds them whatever the input:
 *   tau_ref within +-torque_limit_nm;
 *   position window: outside [position_min, position_max] a tau_ref that
 *     pushes further out is cut to 0 (HD_CTRL_LIM_POSITION);
 *   i_q within +-current_limit_a (HD_CTRL_LIM_CURRENT);
 *   any non-finite intermediate gives i_q = 0, drive disabled and the loop
 *     cleared (HD_CTRL_LIM_NONFINITE).
 * Inputs that make a mode impossible pick a safer mode (hd_ctrl_output_t.mode):
 *   torque feedback needed but not valid or not finite -> DAMP;
 *   velocity not finite -> STOP (nothing safe to damp with);
 *   a setpoint value not finite, or an unknown mode -> DAMP.
 */
#ifndef HD_CTRL_H
#define HD_CTRL_H

#include <stdbool.h>
#include <stdint.h>

#include "hd_artifact.h"

#ifdef __cplusplus
extern "C" {
#endif

/* The one error vocabulary of control/. */
typedef enum {
    HD_CTRL_OK = 0,
    HD_CTRL_ERR_NULL = -1,
    HD_CTRL_ERR_CONFIG = -2,  /* a configuration value non-finite or out of range */
} hd_ctrl_err_t;

typedef enum {
    HD_CTRL_STOP = 0,
    HD_CTRL_DAMP = 1,
    HD_CTRL_TORQUE = 2,
    HD_CTRL_IMPEDANCE = 3,
    HD_CTRL_ZERO_TORQUE = 4,
    HD_CTRL_MODE_COUNT = 5,
} hd_ctrl_mode_t;

typedef enum {
    HD_CTRL_FB_FILTERED = 0,
    HD_CTRL_FB_RAW = 1,
    HD_CTRL_FB_LOWPASS = 2,
    HD_CTRL_FB_NONE = 3,
    HD_CTRL_FB_NARROW = 4,
    HD_CTRL_FB_COUNT = 5,
} hd_ctrl_feedback_t;

/* hd_ctrl_output_t.limits: which limit shaped this step's command. */
#define HD_CTRL_LIM_TORQUE     0x01u
#define HD_CTRL_LIM_VELOCITY   0x02u
#define HD_CTRL_LIM_POSITION   0x04u
#define HD_CTRL_LIM_CURRENT    0x08u
#define HD_CTRL_LIM_NONFINITE  0x10u
#define HD_CTRL_LIM_FALLBACK   0x20u  /* the step ran a safer mode than asked */

#define HD_CTRL_NOTCH_MAX 8u      /* notch_mask bits: orders 1..8 */
#define HD_CTRL_BIQUAD_MAX 2u     /* a 4th-order Butterworth */

/* Ranges hd_ctrl_config_check enforces (and a setpoint's kp/kd must meet). */
#define HD_CTRL_KP_MAX_NM_RAD 2000.0f
#define HD_CTRL_KD_MAX_NM_S_RAD 50.0f
#define HD_CTRL_TORQUE_GAIN_MAX 50.0f
#define HD_CTRL_KI_MAX_PER_S 5000.0f
#define HD_CTRL_TORQUE_KD_MAX_S 0.1f
#define HD_CTRL_INTEGRAL_STIFFNESS_MAX_NM_RAD 1e6f

typedef struct {
    float ts_s;                    /* tick period */
    float gear_ratio;              /* N: joint torque = N motor torque (ideal gear) */
    float kt_nm_per_a;             /* the drive's torque constant (motor N m per A) */
    uint8_t feedback;              /* hd_ctrl_feedback_t (a byte: the firmware's
                                      parameter table holds it as U8) */
    float torque_kp;               /* kp_t: joint N m of u per N m of error */
    float torque_ki_per_s;         /* ki_t */
    float torque_ff;               /* ff: share of tau_ref fed forward, 0..1 */
    float torque_kd_s;             /* kd_t: joint N m of u per N m/s of the feedback's rate */
    float integral_limit_nm;       /* |I| at most this (joint N m; also at most the
                                      current limit's torque) */
    float integral_stiffness_nm_rad; /* IMPEDANCE kp at which the integral runs at the full
                                      ki_t; below, ki_t sqrt(kp / this) (see above) */
    float lowpass_hz;              /* HD_CTRL_FB_LOWPASS corner */
    uint8_t lowpass_order;         /* 1, 2 or 4 (2, 4: Butterworth) */
    uint8_t notch_mask;            /* bit k-1: a notch at motor order k on the raw torque */
    float notch_width_hz;          /* each notch's -3 dB width */
    uint8_t artifact_mask;         /* HD_CTRL_FB_NARROW: bit k-1, a phasor at motor order k */
    float artifact_hz;             /* HD_CTRL_FB_NARROW: the phasors' corner */
    float friction_nm;             /* joint-side Coulomb friction compensated (0: off) */
    float friction_velocity_rad_s; /* v_eps: the compensation fades in over |v| < v_eps */
    float friction_rest_nm;        /* F_r: joint-side friction compensated at rest in the
                                      direction the setpoint torque moves (0: off) */
    float friction_rate_nm_s;      /* r_eps: F_r fades in over |setpoint rate| < r_eps */
    float damp_nm_s_rad;           /* DAMP's damping */
    float torque_limit_nm;         /* |tau_ref| */
    float current_limit_a;         /* |i_q| */
    float velocity_limit_rad_s;    /* TORQUE mode's |v| */
    float velocity_gain_nm_s_rad;  /* how hard the velocity limit pushes back */
    float position_min_rad;        /* position window (output angle) */
    float position_max_rad;
} hd_ctrl_config_t;

typedef struct {
    hd_ctrl_mode_t mode;
    float torque_nm;          /* TORQUE setpoint, IMPEDANCE feed-forward */
    float position_rad;       /* IMPEDANCE q_d */
    float velocity_rad_s;     /* IMPEDANCE v_d */
    float kp_nm_rad;          /* IMPEDANCE stiffness, 0..HD_CTRL_KP_MAX_NM_RAD */
    float kd_nm_s_rad;        /* IMPEDANCE damping, 0..HD_CTRL_KD_MAX_NM_S_RAD */
} hd_ctrl_setpoint_t;

typedef struct {
    float torque_filtered_nm; /* the pipeline's filtered torque */
    float torque_raw_nm;      /* the gauge's torque before the filter */
    bool torque_valid;        /* the gauge and the filter are usable this tick */
    float angle_rad;          /* output angle */
    float velocity_rad_s;     /* output velocity */
    float motor_angle_rad;    /* motor angle (any origin, wrapped or not: HD_CTRL_FB_NARROW) */
    bool motor_angle_valid;   /* false: HD_CTRL_FB_NARROW feeds back the filtered torque */
} hd_ctrl_input_t;

typedef struct {
    bool enable;              /* drive enabled */
    float current_a;          /* q-axis current command, within +-current_limit_a */
    float motor_torque_nm;    /* current_a kt: the motor torque asked for */
    float torque_ref_nm;      /* the joint torque the loop tracked (after limits) */
    float torque_fb_nm;       /* the feedback it used (0 without) */
    uint8_t limits;           /* HD_CTRL_LIM_* */
    hd_ctrl_mode_t mode;      /* the mode that ran */
} hd_ctrl_output_t;

/* A biquad's coefficients and its state, direct form II transposed:
 * y = b0 x + s0; s0 = b1 x - a1 y + s1; s1 = b2 x - a2 y. */
typedef struct {
    float b0, b1, b2, a1, a2;
} hd_ctrl_sos_t;

typedef struct {
    float s0, s1;
} hd_ctrl_sos_state_t;

/* A configuration and what the law derives from it once (divisions, the
 * Butterworth sections' tangent): built by hd_ctrl_plan, outside the tick. */
typedef struct {
    hd_ctrl_config_t cfg;
    float lowpass_alpha;      /* w ts / (1 + w ts) */
    hd_ctrl_sos_t butter[HD_CTRL_BIQUAD_MAX]; /* pass-through beyond the order's sections */
    float notch_r;            /* pole radius: 1 - pi width ts */
    float narrow_inv_rad_s;   /* 1 / (4 (2 pi artifact_hz)): the motion fraction's scale */
    uint8_t artifact_k_min;   /* the lowest order of artifact_mask (1 without orders) */
} hd_ctrl_plan_t;

typedef struct {
    const hd_ctrl_plan_t *plan; /* by reference: hd_ctrl_start's contract */
    hd_ctrl_sos_state_t butter[HD_CTRL_BIQUAD_MAX];
    hd_ctrl_sos_t notch[HD_CTRL_NOTCH_MAX]; /* retuned to the speed each tick */
    hd_ctrl_sos_state_t notch_state[HD_CTRL_NOTCH_MAX];
    float integral_nm;        /* I */
    float fb_prev_nm;         /* the feedback of the loop's last tick (kd_t) */
    bool fb_primed;           /* fb_prev_nm is from the previous tick */
    float lowpass_nm;         /* the low-pass state */
    bool lowpass_primed;
    float raw_notched_nm;     /* the raw torque after the notches, this tick */
    hd_artifact_t artifact;   /* HD_CTRL_FB_NARROW's phasors */
    float narrow_nm;          /* HD_CTRL_FB_NARROW's feedback, this tick */
    bool narrow_ok;           /* narrow_nm is from this tick's inputs */
    float sp_torque_prev_nm;  /* the setpoint torque of the last tick (its rate) */
    bool sp_torque_primed;
} hd_ctrl_t;

/* Defaults of a 40 N m class joint (docs/results/control.md). */
void hd_ctrl_config_default(hd_ctrl_config_t *cfg);

/* HD_CTRL_OK or HD_CTRL_ERR_CONFIG (every value finite, in range). */
int hd_ctrl_config_check(const hd_ctrl_config_t *cfg);

/* Checks cfg and derives the plan from it: HD_CTRL_OK, or an error with *p
 * unchanged.  Slow (divisions, a tangent): outside the tick. */
int hd_ctrl_plan(hd_ctrl_plan_t *p, const hd_ctrl_config_t *cfg);

/* Starts the law on plan p with a cleared loop.  p is kept by reference:
 * it must stay valid and unchanged while c uses it (hd_ctrl_step), as
 * littlefs keeps its lfs_config.  Cheap: the tick may call it. */
void hd_ctrl_start(hd_ctrl_t *c, const hd_ctrl_plan_t *p);

/* Moves the running law to plan p, which must differ from its plan at most
 * in artifact_mask (the filter's motor orders): the loop keeps its state
 * (no torque bump when a filter block is switched), the phasors of orders
 * that leave the mask are cleared, those that enter start at 0.  p is kept
 * by reference as in hd_ctrl_start. */
void hd_ctrl_replan(hd_ctrl_t *c, const hd_ctrl_plan_t *p);

/* hd_ctrl_plan into *p, then hd_ctrl_start(c, p).  On error *c and *p are
 * unchanged. */
int hd_ctrl_init(hd_ctrl_t *c, hd_ctrl_plan_t *p, const hd_ctrl_config_t *cfg);

/* Clears the loop's state (integral, low-pass). */
void hd_ctrl_reset(hd_ctrl_t *c);

/* true when every value of sp is finite, the mode known and kp, kd within
 * their ranges: what the firmware checks before it accepts a setpoint. */
bool hd_ctrl_setpoint_valid(const hd_ctrl_setpoint_t *sp);

/* One tick.  Never fails: whatever sp and in hold, out->current_a is finite
 * and within +-cfg.current_limit_a, and 0 with the drive disabled in STOP. */
void hd_ctrl_step(hd_ctrl_t *c, const hd_ctrl_setpoint_t *sp, const hd_ctrl_input_t *in,
                  hd_ctrl_output_t *out);

const char *hd_ctrl_mode_name(int mode);

#ifdef __cplusplus
}
#endif

#endif /* HD_CTRL_H */
