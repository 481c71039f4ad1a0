/* hd_kf_step: the filter's step (hd_kf.h; docs/design/filter.md, "The step"). */
#include <math.h> /* fabsf */
#include <stddef.h>

#include "hd_kf_frames.h"
#include "hd_kf_gates.h"
#include "hd_kf_internal.h"
#include "hd_trig.h"

/* The step's probes: a block tile with trace in [0, p_max] and
 * determinant >= 0 has both model-coordinate diagonals in [0, p_max]
 * whatever its frame; the sum of the traces (and P_oo) is compared with
 * p_max (not a number fails too), the sign bits of every trace,
 * determinant and P_oo are ORed. */
typedef struct {
    float traces;   /* sum of the block traces and P_oo */
    uint32_t signs; /* OR of the bit patterns of traces, determinants, P_oo */
} bound_probe_t;

/* The step's inputs as the blocks see them: increments and row scales by
 * lock. */
typedef struct {
    float inc[3];          /* motor, output, 1 (the fixed blocks' unit) */
    float rows[3];         /* measurement-row scale: 1 + k |T_ref|, 1, 1 */
    uint32_t short_slots;  /* the motor blocks' short plan (every enabled motor
                              block at motion 1, none frozen): their slots */
    uint32_t free_slots;   /* the output blocks' (none frozen): their slots */
} step_io_t;

/* What the plan of the blocks adds up. */
typedef struct {
    float ripple;          /* prior ripple C x (without the offset) */
    uint32_t partial;      /* blocks with a gain fraction below 1 */
    uint32_t frozen;       /* by configured block */
    uint32_t lost;         /* phase lost: restart */
} plan_sum_t;

/* Block s's part of this step: measurement row h (in its frame: c (cos phi,
 * sin phi), 0 when frozen or disabled), gain fraction f and process noise q
 * per state.  A disabled block gets a zero row, no q and gain 1 (its
 * states and covariances are zero: no weight applies to them). */
KF_INLINE void plan_block(const hd_kf_t *kf, unsigned s, const step_io_t *io, float *h,
                          float *f, float *q, plan_sum_t *sum)
{
    const hd_kf_slot_t *sl = &kf->slot[s];
    if ((io->short_slots & (1u << s)) != 0u) {
        /* what the rules below give at motion 1, not frozen */
        const float row = io->rows[HD_KF_LOCK_MOTOR];
        h[0] = row * kf->phasor_cos[sl->frame];
        h[1] = row * kf->phasor_sin[sl->frame];
        *f = 1.0f;
        *q = sl->q_nm2;
        sum->ripple += h[0] * kf->x[2u * s];
        sum->ripple += h[1] * kf->x[2u * s + 1u];
        return;
    }
    if ((io->free_slots & (1u << s)) != 0u) {
        /* an output block not frozen: its row entry is 1, its gain learn
         * (partial slots: set by the caller) */
        const float a = fabsf(sl->theta_per_unit * io->inc[HD_KF_LOCK_OUTPUT]);
        const float motion = a * sl->motion_inv + sl->motion_bias;
        const float row = (kf->follow_slots & (1u << s)) != 0u ? io->rows[HD_KF_LOCK_OUTPUT]
                                                               : 1.0f;
        h[0] = row * kf->phasor_cos[sl->frame];
        h[1] = row * kf->phasor_sin[sl->frame];
        *f = sl->learn;
        *q = sl->q_nm2 * (motion < 1.0f ? motion : 1.0f);
        sum->ripple += h[0] * kf->x[2u * s];
        sum->ripple += h[1] * kf->x[2u * s + 1u];
        return;
    }
    if (UNLIKELY(!sl->enabled)) {
        h[0] = h[1] = *q = 0.0f;
        *f = 1.0f;
        return;
    }
    const unsigned lock = sl->lock;
    const float a = fabsf(sl->theta_per_unit * io->inc[lock]);
    float motion = a * sl->motion_inv + sl->motion_bias;
    motion = motion < 1.0f ? motion : 1.0f;
    /* a motor block learns as it turns; learn is 1 for motor blocks */
    float gain = lock == HD_KF_LOCK_MOTOR ? motion : sl->learn;
    float qs = sl->q_nm2 * motion;
    float row = lock != HD_KF_LOCK_OUTPUT || (kf->follow_slots & (1u << s)) != 0u ? io->rows[lock]
                                                                                : 1.0f;
    if (UNLIKELY(!(a <= kf->nyquist_limit_rad))) {
        /* Held: not observed, not corrected, no process noise, still
         * turned by the increment (exact at any speed), unless no motion
         * can explain it (an encoder fault). */
        sum->frozen |= 1u << s;
        gain = qs = row = 0.0f;
        if (!(a <= HD_KF_PHASE_LOST_RAD)) {
            sum->lost |= 1u << s;
        }
    }
    if (gain < 1.0f) {
        sum->partial |= 1u << s;
    }
    h[0] = row * kf->phasor_cos[sl->frame];
    h[1] = row * kf->phasor_sin[sl->frame];
    *f = gain;
    *q = qs;
    sum->ripple += h[0] * kf->x[2u * s];
    sum->ripple += h[1] * kf->x[2u * s + 1u];
}

/* g = (P + Q) C' over the packed tiles, P + Q being the prior's
 * covariance (Q is diagonal: it is added to the diagonal tiles as they are
 * read, and stored by correct); returns C (P + Q) C'.  Each off-diagonal
 * tile adds to both its rows' and its columns' entries of g; sums
 * accumulate term by term (one multiply-accumulate each), rows above
 * first.  The offset's row entry is 1. */
KF_INLINE float cross_covariance(const float *restrict p, const float *restrict h,
                                 const float *restrict q, float q_off, float *restrict g,
                                 unsigned nb)
{
    float acc[2u * HD_KF_MAX_BLOCKS + 1u]; /* column sums of the rows above */
    float g_off = 0.0f, cpc = 0.0f;
    KF_UNROLL
    for (unsigned s = 0; s < nb; s++) {
        const float h0 = h[2u * s], h1 = h[2u * s + 1u];
        const float pa = p[0] + q[s], pd = p[2] + q[s];
        float ga = s == 0u ? pa * h0 : acc[2u * s] + pa * h0;
        float gb = s == 0u ? p[1] * h0 : acc[2u * s + 1u] + p[1] * h0;
        ga += p[1] * h1;
        gb += pd * h1;
        p += 3;
        KF_UNROLL
        for (unsigned t = s + 1u; t < nb; t++, p += 4) {
            const float k0 = h[2u * t], k1 = h[2u * t + 1u];
            ga += p[0] * k0;
            ga += p[1] * k1;
            gb += p[2] * k0;
            gb += p[3] * k1;
            float t0 = s == 0u ? p[0] * h0 : acc[2u * t] + p[0] * h0;
            float t1 = s == 0u ? p[1] * h0 : acc[2u * t + 1u] + p[1] * h0;
            t0 += p[2] * h1;
            t1 += p[3] * h1;
            acc[2u * t] = t0;
            acc[2u * t + 1u] = t1;
        }
        ga += p[0];
        gb += p[1];
        g_off += p[0] * h0;
        g_off += p[1] * h1;
        p += 2;
        g[2u * s] = ga;
        g[2u * s + 1u] = gb;
        cpc += h0 * ga;
        cpc += h1 * gb;
    }
    g_off += p[0] + q_off;
    cpc += g_off;
    g[2u * nb] = g_off;
    return cpc;
}

/* A block's diagonal tile [a b; b d]: Q added (the prior), downdate with
 * weights (wa, wb), into the probe. */
KF_INLINE void correct_diag_tile(float *p, float wa, float wb, float ga, float gb, float q,
                                 bound_probe_t *probe)
{
    const float a = (p[0] + q) - wa * ga, b = p[1] - wa * gb;
    const float d = (p[2] + q) - wb * gb;
    p[0] = a;
    p[1] = b;
    p[2] = d;
    const float trace = a + d;
    probe->traces += trace;
    probe->signs |= bits_of(trace) | bits_of(a * d - b * b);
}

/* A block's unchanged diagonal tile into the probe. */
KF_INLINE void probe_diag_tile(const float *p, bound_probe_t *probe)
{
    const float trace = p[0] + p[2];
    probe->traces += trace;
    probe->signs |= bits_of(trace) | bits_of(p[0] * p[2] - p[1] * p[1]);
}

/* The Joseph tiles: tile (s, t) with W_st = f_s + f_t - f_s f_t below 1,
 * i.e. both blocks' fractions below 1 (partial), which the unrolled pass
 * leaves; the weight is 1 wherever one of the fractions is 1.  A frozen
 * block's fraction is 0: W is 0 between two frozen blocks (those tiles and
 * a frozen block's own, which gets no q either, stay as they are). */
static void correct_partial(float *p, const float *g, const float *f, const float *q,
                            float inv_s, unsigned nb, uint32_t partial, uint32_t frozen,
                            bound_probe_t *probe)
{
    for (uint32_t rows = partial; rows != 0u; rows &= rows - 1u) {
        const unsigned s = (unsigned)__builtin_ctz(rows);
        float *row = &p[tile_row_start(nb, s)];
        const float fs = f[s], ga = g[2u * s], gb = g[2u * s + 1u];
        const float ua = ga * inv_s, ub = gb * inv_s;
        uint32_t cols = partial & ~((2u << s) - 1u);
        if ((frozen & (1u << s)) != 0u) {
            probe_diag_tile(row, probe);
            cols &= ~frozen;
        } else {
            const float ws = fs + fs - fs * fs;
            correct_diag_tile(row, ws * ua, ws * ub, ga, gb, q[s], probe);
        }
        for (; cols != 0u; cols &= cols - 1u) {
            const unsigned t = (unsigned)__builtin_ctz(cols);
            float *tile = row + 3u + 4u * (t - s - 1u);
            const float w = fs + f[t] - fs * f[t];
            const float wa = w * ua, wb = w * ub;
            tile[0] -= wa * g[2u * t];
            tile[1] -= wa * g[2u * t + 1u];
            tile[2] -= wb * g[2u * t];
            tile[3] -= wb * g[2u * t + 1u];
        }
    }
}

/* x <- x + F g k_e and P <- (P + Q) - W .* g g' / S in the frames, where
 * the step's rotation is only a turn of the frames (advance_frames), so P + Q
 * is the prior's covariance: each tile loaded once, Q added, downdated,
 * stored once.  W_st = f_s + f_t - f_s f_t
 * (the Joseph form for the gain F g / S) is 1 unless both fractions are
 * below 1 (the offset's fraction is 1): those tiles, in partial, are left to
 * correct_partial.  inv_s = k_e = 0: prediction only. */
KF_INLINE void correct(float *restrict p, float *restrict x, const float *restrict g,
                       const float *restrict f, const float *restrict q, float inv_s, float k_e,
                       float q_off, unsigned nb, uint32_t partial, uint32_t frozen,
                       bound_probe_t *probe)
{
    float *const p_start = p;
    const float g_off = g[2u * nb];
    bound_probe_t worst = {0.0f, 0u};
    KF_UNROLL
    for (unsigned s = 0; s < nb; s++, x += 2) {
        const float ga = g[2u * s], gb = g[2u * s + 1u];
        const float fk = f[s] * k_e;
        x[0] += ga * fk;
        x[1] += gb * fk;
        const float ua = ga * inv_s, ub = gb * inv_s;
        if ((partial & (1u << s)) == 0u) {
            correct_diag_tile(p, ua, ub, ga, gb, q[s], &worst);
        }
        p += 3;
        KF_UNROLL
        for (unsigned t = s + 1u; t < nb; t++, p += 4) {
            const uint32_t both = (1u << s) | (1u << t);
            if ((partial & both) != both) {
                p[0] -= ua * g[2u * t];
                p[1] -= ua * g[2u * t + 1u];
                p[2] -= ub * g[2u * t];
                p[3] -= ub * g[2u * t + 1u];
            }
        }
        p[0] -= ua * g_off;
        p[1] -= ub * g_off;
        p += 2;
    }
    p[0] = (p[0] + q_off) - g_off * inv_s * g_off;
    worst.traces += p[0];
    worst.signs |= bits_of(p[0]);
    x[0] += g_off * k_e;
    if (UNLIKELY(partial != 0u)) {
        /* copies, so that g, f, q and worst stay in registers elsewhere */
        float gc[HD_KF_MAX_STATES], fc[HD_KF_MAX_BLOCKS], qc[HD_KF_MAX_BLOCKS];
        KF_UNROLL
        for (unsigned s = 0; s < nb; s++) {
            gc[2u * s] = g[2u * s];
            gc[2u * s + 1u] = g[2u * s + 1u];
            fc[s] = f[s];
            qc[s] = q[s];
        }
        bound_probe_t joseph = {0.0f, 0u};
        correct_partial(p_start, gc, fc, qc, inv_s, nb, partial, frozen, &joseph);
        worst.traces += joseph.traces;
        worst.signs |= joseph.signs;
    }
    *probe = worst;
}

/* The step's measurement variance: R plus T_exp's own (hd_kf_input_t). */
KF_INLINE float measurement_var(const hd_kf_t *kf, float expected_var_nm2)
{
    const float v = expected_var_nm2 > 0.0f ? expected_var_nm2 : 0.0f; /* NaN: 0 */
    return kf->cfg.r_nm2 + (v < HD_KF_MAX_EXPECTED_VAR_NM2 ? v : HD_KF_MAX_EXPECTED_VAR_NM2);
}

/* The output phasor's powers (rare: output orders above 1), out of line. */
static void output_phasor_powers(hd_kf_t *kf)
{
    phasor_powers(kf->output_powers, kf->phasor_cos + POWER_TABLE_OUTPUT,
                  kf->phasor_sin + POWER_TABLE_OUTPUT);
}

/* The output phasor from the exactly accumulated output phase: a slow
 * output (|increment| <= SMALL_ANGLE_RAD) turns by the series sin/cos,
 * cheaper than the sin/cos of the whole phase, and is set again from the
 * exact sum every OUTPUT_TURNS_MAX steps (the drift, < 3e-11 rad per step,
 * never accumulates); a faster one is set from the sum every step: sin/cos
 * of hi, then the first-order term in lo (|lo| <= 2.4e-7: the next term is
 * below 3e-14). */
KF_INLINE void advance_output_frame(hd_kf_t *kf, float d)
{
    float *c = &kf->phasor_cos[POWER_TABLE_OUTPUT + 1u];
    float *s = &kf->phasor_sin[POWER_TABLE_OUTPUT + 1u];
    add_phase(&kf->output_phase_hi_rad, &kf->output_phase_lo_rad, d);
    if (kf->output_turns < OUTPUT_TURNS_MAX && fabsf(d) <= SMALL_ANGLE_RAD) {
        float sn, cs;
        sincos_series(d, &sn, &cs);
        turn_phasor(c, s, cs, sn);
        kf->output_turns++;
    } else {
        const float lo = kf->output_phase_lo_rad;
        float sh, ch;
        hd_sincosf(kf->output_phase_hi_rad, &sh, &ch);
        *c = ch - lo * sh;
        *s = sh + lo * ch;
        kf->output_turns = 0u;
    }
}


/* The step's rotation Phi: each block's frame turns by its phase advance.
 * Integral orders take powers of the motor and output phasors; the others
 * turn their own.  The motor phasor turns by one sin/cos of the increment:
 * its rounding drifts the phase by ~2e-9 rad per step at constant speed
 * (docs/design/filter.md), which motor-locked blocks, learning all the time, take
 * up.  The output phasor comes from the exactly accumulated output phase:
 * an output-locked block that does not learn (output_learn_scale 0) keeps
 * its profile against the absolute angle for as long as the filter runs. */
KF_INLINE void advance_frames(hd_kf_t *kf, const float inc[3])
{
    if (kf->motor_powers != 0u) {
        float s, c;
        sincos_step(inc[HD_KF_LOCK_MOTOR], &s, &c);
        turn_phasor_raw(&kf->phasor_cos[1], &kf->phasor_sin[1], c, s);
        if ((kf->motor_powers & ~3u) != 0u) {
            phasor_powers(kf->motor_powers, kf->phasor_cos, kf->phasor_sin);
        }
    }
    if (kf->output_powers != 0u) {
        advance_output_frame(kf, inc[HD_KF_LOCK_OUTPUT]);
        if ((kf->output_powers & ~3u) != 0u) {
            output_phasor_powers(kf);
        }
    }
    for (uint32_t left = kf->own_frames; left != 0u; left &= left - 1u) {
        const hd_kf_slot_t *sl = &kf->slot[__builtin_ctz(left)];
        float sn = sl->fixed_sin, cs = sl->fixed_cos;
        if (sl->lock != HD_KF_LOCK_FIXED) {
            sincos_step(sl->theta_per_unit * inc[sl->lock], &sn, &cs);
        }
        turn_phasor(&kf->phasor_cos[sl->frame], &kf->phasor_sin[sl->frame], cs, sn);
    }
}

/* The step for a layout of nb blocks (a constant in each instance, so
 * every loop unrolls and h, g, f, q live in registers): inputs, the time
 * update by this sample's increments (the turn of the frames; its Q is
 * added in the passes over P), the plan of every block, restarts, offset
 * priming, the innovation and its variance against the prior, the offset
 * gate, the outputs, the measurement update and the bounds. */
KF_INLINE void step_layout(hd_kf_t *kf, const hd_kf_input_t *in, hd_kf_output_t *out,
                           unsigned nb)
{
    /* ---- inputs: a non-finite or absurd sample is not corrected; a
     * non-finite increment counts as no motion; the fixed blocks'
     * "increment" is 1 (their phase advance per step) */
    step_io_t io;
    io.inc[HD_KF_LOCK_MOTOR] = in->d_motor_angle_rad;
    io.inc[HD_KF_LOCK_OUTPUT] = in->d_output_angle_rad;
    io.inc[HD_KF_LOCK_FIXED] = 1.0f;
    const float y = in->torque_meas_nm - in->torque_expected_nm;
    const bool valid = fabsf(y) <= HD_KF_MAX_ABS_Y_NM;
    uint32_t status = valid ? 0u : HD_KF_STATUS_BAD_INPUT;
    if (UNLIKELY(!is_finite(io.inc[0] + io.inc[1]))) {
        for (unsigned i = 0; i < 2u; i++) {
            if (!is_finite(io.inc[i])) {
                io.inc[i] = 0.0f;
                status = HD_KF_STATUS_BAD_INPUT;
            }
        }
    }
    const float motor_abs = fabsf(io.inc[HD_KF_LOCK_MOTOR]);
    io.short_slots = motor_abs >= kf->motor_full_rad && motor_abs < kf->motor_frozen_rad
                         ? kf->motor_slots
                         : 0u;
    io.free_slots = fabsf(io.inc[HD_KF_LOCK_OUTPUT]) < kf->output_frozen_rad ? kf->output_slots
                                                                            : 0u;
    const float t_abs = (kf->cfg.ripple_load_coeff_per_nm > 0.0f || kf->output_follow != 0u)
                            ? hd_kf_load_ref(kf, in->torque_expected_nm,
                                              io.inc[HD_KF_LOCK_MOTOR])
                            : 0.0f;
    const float c_load = 1.0f + kf->cfg.ripple_load_coeff_per_nm * t_abs;
    io.rows[HD_KF_LOCK_MOTOR] = c_load;
    io.rows[HD_KF_LOCK_OUTPUT] = io.rows[HD_KF_LOCK_FIXED] = 1.0f;
    const bool lines_observed = motor_abs >= kf->follow_min_rad && motor_abs < kf->motor_frozen_rad;
    if (lines_observed) {
        hd_kf_learn_load(kf, in->torque_expected_nm);
    }
    if (UNLIKELY(kf->output_follow != 0u)) {
        status |= hd_kf_follow_motor_lines(kf, t_abs, lines_observed);
        io.rows[HD_KF_LOCK_OUTPUT] = kf->output_row;
    }

    /* ---- time update: the posterior of the last sample turns by this
     * sample's increments (Phi is a turn of the frames; the plan below
     * reads the turned ones) */
    advance_frames(kf, io.inc);

    /* ---- what this step does to each block */
    float h[2u * HD_KF_MAX_BLOCKS], f[HD_KF_MAX_BLOCKS], q[HD_KF_MAX_BLOCKS];
    float g[HD_KF_MAX_STATES];
    plan_sum_t sum = {0.0f, io.free_slots & kf->output_partial_slots, 0u, 0u};
    KF_UNROLL
    for (unsigned s = 0; s < nb; s++) {
        plan_block(kf, s, &io, &h[2u * s], &f[s], &q[s], &sum);
    }
    if (UNLIKELY(sum.lost != 0u)) {
        hd_kf_restart_lost_blocks(kf, sum.lost);
    }

    /* ---- innovation and its variance (the prior's) */
    const float ripple = sum.ripple;
    const unsigned o = 2u * nb;
    if (UNLIKELY(!kf->offset_primed) && kf->cfg.offset_enabled && valid) {
        kf->x[o] = y - ripple;
        kf->offset_primed = 1u;
    }
    const float offset = kf->x[o]; /* 0 when the offset is disabled */
    const float innovation = y - ripple - offset;
    const bool drift_gated = valid && kf->cfg.offset_enabled &&
                             kf->cfg.offset_drift_q_nm2 > kf->offset_q_nm2;
    const float q_off = UNLIKELY(drift_gated) ? offset_drift(kf, kf->offset_q_nm2)
                                              : kf->offset_q_nm2;
    float s_var = measurement_var(kf, in->torque_expected_var_nm2) +
                  cross_covariance(kf->p, h, q, q_off, g, nb);
    bool rollback = false;
    const uint32_t gate =
        valid ? offset_jump(kf, innovation, s_var, io.inc[HD_KF_LOCK_MOTOR], &rollback) : 0u;
    status |= gate;
    if (UNLIKELY(gate == HD_KF_STATUS_OFFSET_JUMP)) {
        /* an offset jump widens the offset's variance first; the jump takes
         * the innovation */
        const float e2 = innovation * innovation;
        kf->p[packed_entries(nb) - 1u] += e2;
        g[o] += e2;
        s_var += e2;
    }
    if (UNLIKELY(gate != 0u) && drift_gated) {
        /* beyond the jump gate: the load is not the known one, the offset
         * follows at offset_drift_q_nm2 from the next step */
        kf->drift_hold_steps = kf->drift_hold_total;
    }

    /* ---- outputs */
    out->ripple_nm = ripple;
    out->offset_nm = offset;
    out->innovation_nm = valid ? innovation : 0.0f;
    out->innovation_var_nm2 = s_var;
    const float correction = ripple + (kf->cfg.offset_is_sensor_error ? offset : 0.0f);
    float filtered = in->torque_meas_nm - correction;
    bool restart = false;
    if (kf->cfg.correction_max_nm > 0.0f) {
        status |= limit_correction(kf, in->torque_meas_nm, correction, out, &filtered, &restart);
    }
    out->torque_filtered_nm = filtered;
    out->frozen_mask = sum.frozen;

    /* ---- correct; bounds on the slow path */
    const float inv_s = valid ? 1.0f / s_var : 0.0f;
    const float k_e = valid ? innovation * inv_s : 0.0f;
    /* S is not finite when some g is not (each enters C P C'), the ripple
     * when some state is not: then neither are the new states */
    const float finite_probe = ripple + offset + s_var + k_e;
    bound_probe_t probe;
    correct(kf->p, kf->x, g, f, q, inv_s, k_e, q_off, nb, sum.partial, sum.frozen, &probe);
    kf->frozen_mask = sum.frozen;
    kf->load_scale = c_load;
    if (UNLIKELY(restart) && event_restores(kf)) {
        restart = false; /* at the limit within a transient: back to its start */
        rollback = true;
    }
    if (UNLIKELY(rollback)) {
        /* a transient's torque, not a line: the blocks as before it */
        for (unsigned i = 0; i < o; i++) {
            kf->x[i] = kf->event_x[i];
        }
        kf->rollback_count++;
    }
    normalize_phasor(&kf->phasor_cos[1], &kf->phasor_sin[1]); /* (1, 0) if unused: kept */
    if (UNLIKELY(!(probe.traces <= kf->cfg.p_max_nm2) || (probe.signs & FLOAT_SIGN_BIT) != 0u ||
                 !is_finite(finite_probe))) {
        const uint32_t bounded = hd_kf_bound_covariance(kf, finite_probe);
        restart = restart || (bounded & HD_KF_STATUS_RESET) != 0u;
        status |= bounded;
    }
    if (UNLIKELY(restart)) {
        hd_kf_reset(kf);
        kf->reset_count++;
        status |= HD_KF_STATUS_RESET;
    }
    if (sum.frozen != 0u) {
        status |= HD_KF_STATUS_FROZEN;
    }
    if (status & HD_KF_STATUS_BAD_INPUT) {
        kf->bad_input_count++;
    }
    out->status = status;
    kf->status_sticky |= status;
    if (UNLIKELY(!is_finite(filtered))) {
        /* Never publish a non-finite estimate: fall back to the measurement
         * (or 0 if that is not finite either). */
        out->torque_filtered_nm = is_finite(in->torque_meas_nm) ? in->torque_meas_nm : 0.0f;
        out->ripple_nm = 0.0f;
    }
}

/* One instance per layout size (build_layout). */
#define STEP_INSTANCE(NAME, N)                                                     \
    static __attribute__((noinline)) void step_##NAME(hd_kf_t *kf, const hd_kf_input_t *in, \
                                                      hd_kf_output_t *out)         \
    {                                                                              \
        step_layout(kf, in, out, (N) < HD_KF_MAX_BLOCKS ? (N) : HD_KF_MAX_BLOCKS); \
    }
STEP_INSTANCE(2, 2u)
STEP_INSTANCE(3, 3u)
STEP_INSTANCE(4, 4u)
STEP_INSTANCE(max, HD_KF_MAX_BLOCKS)

void hd_kf_step(hd_kf_t *kf, const hd_kf_input_t *in, hd_kf_output_t *out)
{
    switch (kf->n_blocks) {
    case 2: step_2(kf, in, out); break;
    case 3: step_3(kf, in, out); break;
    case 4: step_4(kf, in, out); break;
    default: step_max(kf, in, out); break;
    }
}
