/*
 * hd_sim_scenario: the simulated joint's configuration and its text format.
 *
 * Format: one `key = value` per line, `#` starts a comment, blank lines are
 * ignored, values may be wrapped in double quotes.  Scalar keys may appear
 * once; list keys (`ripple`) may repeat and append.  Integers are decimal
 * (a leading zero is an error: "01024" is not octal), numbers have no hex
 * form.  Unknown keys, repeated scalar keys (with the line of the first),
 * NUL, control or non-UTF-8 bytes, lines over 4095 characters, files over
 * 1 MiB or that are not regular files, and malformed or out-of-range values
 * are rejected with "file:line: message".  All keys, units and defaults:
 * docs/reference/sim.md.
 *
 * Host-only (double precision, no allocation needed: fixed-size lists).
 */
#ifndef HD_SIM_SCENARIO_H
#define HD_SIM_SCENARIO_H

#include <stddef.h>
#include <stdint.h>

#include "hd_bridge.h"

#ifdef __cplusplus
extern "C" {
#endif

#define HD_SIM_MAX_POINTS 64   /* breakpoints per piecewise-linear profile */
#define HD_SIM_MAX_RIPPLES 16  /* ripple / pickup lines */
#define HD_SIM_MAX_FAULTS 8    /* encoder fault windows, feed-forward dropouts */
#define HD_SIM_MAX_SINES 8     /* slow sinusoidal load components */
#define HD_SIM_MAX_SAMPLES 100000000ull /* 27.7 h at 1 kHz */

typedef enum {
    HD_SIM_RIPPLE_MOTOR = 0,  /* order = cycles per motor (wave generator) rev */
    HD_SIM_RIPPLE_OUTPUT = 1, /* order = cycles per output rev (1 = misalignment) */
    HD_SIM_RIPPLE_FIXED = 2,  /* order = frequency in Hz (electrical pickup) */
} hd_sim_ripple_kind_t;

typedef struct {
    int kind;            /* hd_sim_ripple_kind_t */
    double order;        /* cycles per rev, or Hz for FIXED */
    double amplitude_nm; /* at zero load (see ripple_load_coeff_per_nm) */
    double phase_rad;    /* line = amplitude * sin(order * angle + phase) */
} hd_sim_ripple_t;

/* Piecewise linear in time; held constant before the first and after the
 * last point.  n = 0 means constantly 0. */
typedef struct {
    size_t n;
    double t_s[HD_SIM_MAX_POINTS];
    double value[HD_SIM_MAX_POINTS];
} hd_sim_profile_t;

typedef struct {
    double t_start_s;
    double t_end_s;
} hd_sim_window_t;

/* One slow load component: amplitude sin(2 pi t / period + phase). */
typedef struct {
    double amplitude_nm;
    double period_s;
    double phase_rad;
} hd_sim_sine_t;

/* The robot controller's model of the joint torque, sent as feed-forward
 * (docs/reference/sim.md, "Feed-forward and motor current"): its own gravity and
 * dynamics parameters, never the plant's truth unless a scenario says so. */
typedef struct {
    int enabled;                     /* 1: the CSV column and hdjoint-host's frames */
    double gravity_scale;            /* its m g l over the truth's (payload estimate error) */
    double gravity_phase_error_rad;  /* its posture offset error */
    hd_sim_profile_t gravity;        /* its own m g l over time; n = 0: the true profile */
    double load_scale;               /* share of the external load it knows (0: unknown) */
    double inertia_kgm2;             /* its J, b, Fc (0: it models none) */
    double viscous_nm_s_rad;
    double coulomb_nm;
    double noise_nm;                 /* Gaussian std of each value */
    uint32_t period_ms;              /* one frame every this many samples (>= 1) */
    hd_sim_window_t dropouts[HD_SIM_MAX_FAULTS]; /* no frames inside these */
    size_t dropout_count;
} hd_sim_feedforward_t;

/* The motor and its current (docs/reference/sim.md): i = T_motor / kt_true. */
typedef struct {
    double kt_nm_per_a;              /* datasheet torque constant; 0 = no current channel */
    double kt_error;                 /* kt_true = kt (1 + kt_error) */
    double efficiency;               /* gear efficiency, power motor -> load */
    double backdrive_efficiency;     /* power load -> motor */
    double coulomb_nm;               /* motor-side friction, at the motor shaft */
    double viscous_nm_s_rad;         /* per motor rad/s */
    double inertia_kgm2;             /* rotor + wave generator */
    double current_noise_a;          /* Gaussian std of the measured current */
} hd_sim_motor_t;

typedef struct {
    /* run */
    double duration_s;
    double ts_s;
    uint64_t seed;
    /* drive and load (the truth) */
    double gear_ratio;
    double motor_angle0_rad;
    hd_sim_profile_t motor_speed;  /* rad/s of the motor (wave generator) */
    hd_sim_profile_t load_torque;  /* external load torque at the output, N m */
    double load_inertia_kgm2;
    double viscous_nm_s_rad;
    double coulomb_nm;
    double stribeck_nm;              /* extra breakaway friction (not told to the filter) */
    double stribeck_velocity_rad_s;
    hd_sim_profile_t gravity;        /* arm link: m g l [N m] over time (payload changes) */
    double gravity_phase_rad;        /* gravity torque = m g l sin(theta_out + phase) */
    hd_sim_sine_t load_sines[HD_SIM_MAX_SINES]; /* added to load_torque */
    size_t load_sine_count;
    hd_sim_feedforward_t ff;
    hd_sim_motor_t motor;
    /* what the sensor adds */
    hd_sim_ripple_t ripples[HD_SIM_MAX_RIPPLES];
    size_t ripple_count;
    double ripple_load_coeff_per_nm; /* motor/output lines scale by 1 + c |torque_true| */
    double offset_nm;
    double offset_drift_nm_per_s;
    double offset_random_walk_nm_per_sqrt_s;
    double noise_nm;                 /* Gaussian std, added as torque before the bridge */
    double noise_v;                  /* Gaussian std, at the amplifier output */
    hd_bridge_config_t bridge;
    double bridge_offset_v;          /* zero offset at the amplifier output */
    /* converters */
    int adc_bits;
    double adc_range_v;              /* ADC spans [-range, +range) */
    uint32_t encoder_cpr;            /* motor encoder counts per rev */
    uint32_t output_encoder_cpr;     /* 0 = no output encoder */
    hd_sim_window_t encoder_faults[HD_SIM_MAX_FAULTS];
    size_t encoder_fault_count;
    /* nominal calibration handed to the firmware; NaN = the true one */
    double cal_gain_nm_per_v;
    double cal_offset_v;
} hd_sim_scenario_t;

/* The paper's drive: ratio 100, 1 kHz, accelerate to 156 rad/s in 0.5 s and
 * hold for 10 s, no ripple, no noise, K = 2, 10 V, G = 1000, 6.60 N m/V,
 * 16-bit ADC over +-10 V, 4096-count motor encoder. */
void hd_sim_scenario_default(hd_sim_scenario_t *sc);

/* Parse a whole file / string on top of the defaults.  name is used in
 * messages.  Returns 0, or -1 with "name:line: message" in err. */
int hd_sim_scenario_load(hd_sim_scenario_t *sc, const char *path, char *err, size_t err_len);
int hd_sim_scenario_parse(hd_sim_scenario_t *sc, const char *text, const char *name,
                          char *err, size_t err_len);
/* The same for text_len bytes that need not be NUL-terminated (a NUL byte
 * inside is an error with its line). */
int hd_sim_scenario_parse_n(hd_sim_scenario_t *sc, const char *text, size_t text_len,
                            const char *name, char *err, size_t err_len);

/* Apply one `key=value` (or key, value) override, e.g. from the command
 * line; scalars may be overridden.  Returns 0 or -1 with a message. */
int hd_sim_scenario_set(hd_sim_scenario_t *sc, const char *key, const char *value,
                        char *err, size_t err_len);

/* Cross-field checks (run by load/parse; call again after set). */
int hd_sim_scenario_validate(const hd_sim_scenario_t *sc, char *err, size_t err_len);

/* Number of samples: round(duration / ts). */
uint64_t hd_sim_scenario_samples(const hd_sim_scenario_t *sc);

/* Profile value at t (piecewise linear, held at the ends). */
double hd_sim_profile_eval(const hd_sim_profile_t *p, double t_s);

#ifdef __cplusplus
}
#endif

#endif /* HD_SIM_SCENARIO_H */
