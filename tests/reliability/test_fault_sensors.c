/* Fault injection on the sensor side, on the simulated joint: bad ADC
 * samples, encoder faults, speed extremes, load steps and ripple changes.
 *
 * For every fault: the ISR takes exactly one step per call (1 kHz, no
 * deadline miss, a telemetry frame pair every tick, no sequence gap),
 * outputs stay finite and bounded, invalid samples are always flagged, the
 * expected fault bit shows in the per-tick faults AND in the telemetry
 * frames, and the filtered torque comes back within FI_BAND_NM of the
 * simulation's ground truth.  The recovery time (ticks from the end of the
 * fault until |filtered - truth| <= 0.15 N m for 200 consecutive ticks) is
 * printed as a `measured:` line (rel_measured.h; tests/reliability/rel_doc.py
 * writes docs/results/reliability.md from them) and must stay under a limit derived
 * from the filter's settle times. */
#include <math.h>
#include <string.h>

#include "fi_rig.h"
#include "rel_measured.h"
#include "unity.h"

static fi_rig_t rig;

/* Recovery limits [ticks].  Samples lost while the encoder keeps the phase:
 * the state is still right, recovery is immediate (a few ticks of margin).
 * Ripple phase/amplitude disturbed, or a block restarted from zero: the
 * ripple blocks settle in ~50 ms (HD_FW_DEFAULT_RIPPLE_SETTLE_S) from a
 * small error; from scratch to inside a 0.15 N m band takes longer, so the
 * limit is 20 settle times = 1000 ticks. */
#define LIMIT_HELD_STATE 20
#define LIMIT_RESETTLE 1000

/* Faults start at 12 s: the output-locked (misalignment) block learns over
 * several output revolutions (4 s each at 156 rad/s); by 12 s the error is
 * inside the band. */
#define T0 12000u

void setUp(void) {}
void tearDown(void) {}

static void assert_invariants(void)
{
    TEST_ASSERT_EQUAL_UINT32_MESSAGE(0, rig.bad_steps, "ISR did not step once per call");
    TEST_ASSERT_EQUAL_UINT32_MESSAGE(0, rig.non_finite, "non-finite output");
    TEST_ASSERT_EQUAL_UINT32_MESSAGE(0, rig.out_of_bounds, "output out of bounds");
    TEST_ASSERT_EQUAL_UINT32_MESSAGE(0, rig.invalid_unflagged, "invalid sample without a flag");
    TEST_ASSERT_EQUAL_UINT32(0, rig.fw.counters.deadline_misses);
    TEST_ASSERT_EQUAL_UINT32((uint32_t)rig.tick, rig.fw.counters.ticks);
    /* telemetry at 1 kHz: one pair per tick, none lost */
    TEST_ASSERT_EQUAL_UINT32((uint32_t)rig.tick, rig.telem_a);
    TEST_ASSERT_EQUAL_UINT32((uint32_t)rig.tick, rig.telem_b);
    TEST_ASSERT_EQUAL_UINT32(0, rig.seq_gaps);
}

/* Converged before the fault: otherwise a recovery time means nothing. */
static void assert_converged_before(uint64_t start)
{
    double m = fi_max_abs_err(&rig, start - 1000u, start);
    TEST_ASSERT_TRUE_MESSAGE(m <= FI_BAND_NM, "filter not converged before the fault");
    TEST_ASSERT_EQUAL_HEX16(0, fi_faults_in(&rig, 0, start));
}

/* The torque the firmware computes from ADC counts with the rig's nominal
 * calibration (what an injected sample means in N m). */
static double sample_nm(int32_t counts)
{
    return rig.nom.gain_nm_per_v * ((double)counts * rig.nom.adc_v_per_count - rig.nom.offset_v);
}

static void test_no_fault_baseline(void)
{
    /* the error the fault cases are compared with: the converged rig over
     * the same span, nothing injected */
    fi_rig_init(&rig, "duration_s = 18\n");
    fi_rig_run(&rig, UINT64_MAX);
    assert_invariants();
    assert_converged_before(T0);
    TEST_ASSERT_EQUAL_HEX32(0, fi_faults_in(&rig, 0, rig.tick));
    double rms = fi_rms_err(&rig, T0, rig.tick);
    double peak = fi_max_abs_err(&rig, T0, rig.tick);
    fi_report_setup(T0);
    rel_measured("no_fault", "rms_err_nm=%.6g max_err_nm=%.6g from_s=%g to_s=%g", rms, peak,
                 (double)T0 / 1000.0, (double)rig.tick / 1000.0);
    /* 0.02 N m of sensor noise: a converged filter stays well inside the band */
    TEST_ASSERT_TRUE(rms < FI_BAND_NM / 3.0);
    TEST_ASSERT_TRUE(peak <= FI_BAND_NM);
}

/* A fault in [start, end) on the base scenario (156 rad/s held from 0.5 s). */
static long window_fault(const char *name, int kind, uint64_t start, uint64_t end, int32_t counts,
                         uint16_t flag, long limit)
{
    fi_rig_init(&rig, "duration_s = 18\n");
    rig.fault.kind = kind;
    rig.fault.start_tick = start;
    rig.fault.end_tick = end;
    rig.fault.counts = counts;
    fi_rig_run(&rig, UINT64_MAX);
    assert_invariants();
    assert_converged_before(start);
    TEST_ASSERT_EQUAL_UINT16_MESSAGE(flag, fi_faults_in(&rig, start, end) & flag, name);
    TEST_ASSERT_EQUAL_UINT16_MESSAGE(flag, rig.telem_faults_or & flag, name);
    TEST_ASSERT_EQUAL_UINT16_MESSAGE(flag, rig.hb_faults_or & flag, name);
    /* the flag goes away with the fault */
    TEST_ASSERT_EQUAL_HEX16(0, fi_faults_in(&rig, end + 2u, rig.tick) & flag);
    long rec = fi_recovery_ticks(&rig, end, FI_BAND_NM, FI_HOLD_TICKS);
    char extra[64];
    snprintf(extra, sizeof extra, "window_ms=%u counts=%ld", (unsigned)(end - start), (long)counts);
    fi_report(&rig, name, rec, limit, fi_max_abs_err(&rig, start, end + 1000u), start, end + 2u, extra);
    TEST_ASSERT_TRUE_MESSAGE(rec >= 0, "never recovered");
    TEST_ASSERT_TRUE_MESSAGE(rec <= limit, "recovery too slow");
    return rec;
}

static void test_adc_read_error_500ms(void)
{
    window_fault("adc_read_error", FI_ADC_IO, T0, T0 + 500u, 0, HD_FAULT_ADC_ERROR, LIMIT_HELD_STATE);
}

static void test_adc_stuck_at_rail_500ms(void)
{
    window_fault("adc_stuck_at_rail", FI_ADC_RAIL, T0, T0 + 500u, 0, HD_FAULT_ADC_SATURATED,
                 LIMIT_HELD_STATE);
}

static void test_open_bridge_500ms(void)
{
    window_fault("open_bridge", FI_OPEN_BRIDGE, T0, T0 + 500u, 0, HD_FAULT_OPEN_BRIDGE,
                 LIMIT_HELD_STATE);
}

static void test_out_of_range_sample_100ms(void)
{
    /* 9.5 V at the ADC = 62.7 N m, inside the ADC span (+-10 V) but above a
     * 50 N m torque limit */
    fi_rig_init(&rig, "duration_s = 18\n");
    rig.fw.settings[rig.fw.live_settings].cfg.torque_limit_nm = 50.0f;
    rig.fault.kind = FI_ADC_COUNTS;
    rig.fault.start_tick = T0;
    rig.fault.end_tick = T0 + 100u;
    rig.fault.counts = (int32_t)lround(9.5 / rig.nom.adc_v_per_count);
    fi_rig_run(&rig, UINT64_MAX);
    assert_invariants();
    TEST_ASSERT_EQUAL_HEX16(HD_FAULT_TORQUE_RANGE, fi_faults_in(&rig, T0, T0 + 100u));
    TEST_ASSERT_EQUAL_HEX16(HD_FAULT_TORQUE_RANGE, rig.telem_faults_or);
    long rec = fi_recovery_ticks(&rig, T0 + 100u, FI_BAND_NM, FI_HOLD_TICKS);
    char extra[96];
    snprintf(extra, sizeof extra, "window_ms=100 sample_nm=%.3g torque_limit_nm=%g",
             sample_nm(rig.fault.counts), (double)hd_fw_config(&rig.fw)->torque_limit_nm);
    fi_report(&rig, "out_of_range_sample", rec, LIMIT_HELD_STATE, (double)NAN, T0, T0 + 100u, extra);
    TEST_ASSERT_TRUE(rec >= 0 && rec <= LIMIT_HELD_STATE);
}

static void test_single_wild_sample_inside_range(void)
{
    /* A one-tick spike of +8 V (about +53 N m) that passes the range check:
     * the firmware cannot tell it from torque.  The offset-jump gate sends it
     * to the offset; the next sample undoes it. */
    fi_rig_init(&rig, "duration_s = 18\n");
    rig.fault.kind = FI_ADC_COUNTS;
    rig.fault.start_tick = T0;
    rig.fault.end_tick = T0 + 1u;
    rig.fault.counts = (int32_t)lround(8.0 / rig.nom.adc_v_per_count);
    fi_rig_run(&rig, UINT64_MAX);
    assert_invariants();
    long rec = fi_recovery_ticks(&rig, T0 + 1u, FI_BAND_NM, FI_HOLD_TICKS);
    char extra[64];
    snprintf(extra, sizeof extra, "sample_nm=%.3g", sample_nm(rig.fault.counts));
    fi_report(&rig, "wild_sample_in_range", rec, LIMIT_RESETTLE,
              fi_max_abs_err(&rig, T0 + 1u, T0 + 1000u), T0, T0 + 2u, extra);
    TEST_ASSERT_TRUE(rec >= 0 && rec <= LIMIT_RESETTLE);
}

static void test_encoder_fault_200ms(void)
{
    /* the firmware dead-reckons with the last good delta: the phase drifts
     * by the speed error over the window and is corrected by the first good
     * read; the ripple blocks re-settle */
    window_fault("encoder_fault", FI_ENC_FAULT, T0, T0 + 200u, 0, HD_FAULT_ENC_FAULT,
                 LIMIT_RESETTLE);
}

static void test_encoder_glitch_one_tick(void)
{
    /* a one-tick spike of 100000 counts: two flagged ticks (out and back) */
    window_fault("encoder_glitch", FI_ENC_SPIKE, T0, T0 + 1u, 100000, HD_FAULT_ENC_GLITCH,
                 LIMIT_HELD_STATE);
    TEST_ASSERT_EQUAL_UINT32(2, rig.fw.counters.by_fault[4]);
    rel_measured("encoder_glitch", "flagged_ticks=%u", (unsigned)rig.fw.counters.by_fault[4]);
}

static void test_encoder_jump_detected(void)
{
    /* the counter jumps by 5000 counts for good (far beyond one tick of
     * travel at the glitch limit): flagged, and because only deltas are
     * used, the angle the filter sees is unaffected */
    window_fault("encoder_jump", FI_ENC_JUMP, T0, T0 + 1u, 5000, HD_FAULT_ENC_GLITCH,
                 LIMIT_HELD_STATE);
    TEST_ASSERT_EQUAL_UINT32(1, rig.fw.counters.by_fault[4]);
    rel_measured("encoder_jump", "flagged_ticks=%u", (unsigned)rig.fw.counters.by_fault[4]);
}

static void test_encoder_lost_counts_undetectable(void)
{
    /* 40 counts lost (3.5 deg of motor angle, 7 deg of order-2 phase): one
     * tick moves 62 instead of 102 counts, which no per-tick check can tell
     * from a speed change.  Not flagged (documented limitation); the ripple
     * blocks must re-estimate their phase. */
    fi_rig_init(&rig, "duration_s = 18\n");
    rig.fault.kind = FI_ENC_JUMP;
    rig.fault.start_tick = T0;
    rig.fault.end_tick = T0 + 1u;
    rig.fault.counts = -40;
    fi_rig_run(&rig, UINT64_MAX);
    assert_invariants();
    TEST_ASSERT_EQUAL_HEX16(0, fi_faults_in(&rig, 0, rig.tick));
    long rec = fi_recovery_ticks(&rig, T0 + 1u, FI_BAND_NM, FI_HOLD_TICKS);
    char extra[64];
    snprintf(extra, sizeof extra, "counts=%d motor_deg=%.2g", -rig.fault.counts,
             -360.0 * rig.fault.counts / (double)rig.nom.motor_cpr);
    fi_report(&rig, "encoder_lost_counts", rec, LIMIT_RESETTLE, fi_max_abs_err(&rig, T0, T0 + 1000u),
              0, rig.tick, extra);
    TEST_ASSERT_TRUE(rec >= 0 && rec <= LIMIT_RESETTLE);
}

/* A speed-profile case: no fault window, recovery from `from`. */
static long profile_case(const char *name, const char *extra, uint64_t from, uint16_t flag_expected,
                         long limit)
{
    fi_rig_init(&rig, extra);
    fi_rig_run(&rig, UINT64_MAX);
    assert_invariants();
    TEST_ASSERT_EQUAL_UINT64(rig.n_ticks, rig.tick);
    uint16_t f = fi_faults_in(&rig, 0, rig.tick);
    TEST_ASSERT_EQUAL_UINT16_MESSAGE(flag_expected, f, name);
    TEST_ASSERT_EQUAL_HEX16(flag_expected, rig.telem_faults_or);
    long rec = fi_recovery_ticks(&rig, from, FI_BAND_NM, FI_HOLD_TICKS);
    fi_report(&rig, name, rec, limit, fi_max_abs_err(&rig, from, rig.tick), 0, rig.tick, NULL);
    TEST_ASSERT_TRUE_MESSAGE(rec >= 0, "never recovered");
    TEST_ASSERT_TRUE_MESSAGE(rec <= limit, "recovery too slow");
    return rec;
}

static void test_direction_reversal(void)
{
    /* +156 -> -156 rad/s in 0.4 s (through zero at 12.2 s) */
    profile_case("direction_reversal",
                 "duration_s = 20\nmotor_speed_profile = 0:0, 0.5:156, 12:156, 12.4:-156\n", T0 + 400u, 0,
                 LIMIT_RESETTLE);
}

static void test_standstill_three_minutes(void)
{
    /* stops at 12.2 s, stands still for 180 s, restarts at 192.2 s */
    fi_rig_init(&rig, "duration_s = 200\n"
                      "motor_speed_profile = 0:0, 0.5:156, 12:156, 12.2:0, 192.2:0, 192.4:156\n");
    fi_rig_run(&rig, UINT64_MAX);
    assert_invariants();
    TEST_ASSERT_EQUAL_HEX16(0, fi_faults_in(&rig, 0, rig.tick));
    /* the covariance stays bounded while nothing moves (motion-scaled q) */
    const hd_kf_t *kf = &rig.fw.pipe[rig.fw.live_pipe].kf;
    for (unsigned i = 0; i < hd_kf_state_count(kf); i++) {
        float pii = hd_kf_cov(kf, i, i);
        TEST_ASSERT_TRUE(isfinite(pii) && pii >= 0.0f && pii <= kf->cfg.p_max_nm2);
    }
    TEST_ASSERT_EQUAL_UINT32(0, kf->reset_count);
    double during = fi_max_abs_err(&rig, T0 + 200u, 192200);
    long rec = fi_recovery_ticks(&rig, 192400, FI_BAND_NM, FI_HOLD_TICKS);
    fi_report(&rig, "standstill", rec, LIMIT_RESETTLE, during, 0, rig.tick, "standstill_s=180");
    TEST_ASSERT_TRUE_MESSAGE(during <= FI_BAND_NM, "error grew at standstill");
    TEST_ASSERT_TRUE(rec >= 0 && rec <= LIMIT_RESETTLE);
}

static void test_order_over_nyquist(void)
{
    /* 900 rad/s: order 4 advances 3.6 rad per tick > 0.9 pi -> frozen;
     * order 2 (1.8 rad) stays.  Back to 156 rad/s at 15 s. */
    fi_rig_init(&rig, "duration_s = 22\n"
                      "motor_speed_profile = 0:0, 0.5:156, 12:156, 12.5:900, 14.5:900, 15:156\n");
    fi_rig_run(&rig, UINT64_MAX);
    assert_invariants();
    TEST_ASSERT_EQUAL_HEX16(HD_FAULT_KF_FROZEN, fi_faults_in(&rig, 12500, 14500));
    TEST_ASSERT_EQUAL_HEX16(HD_FAULT_KF_FROZEN, rig.telem_faults_or);
    TEST_ASSERT_EQUAL_HEX16(0, fi_faults_in(&rig, 15000, rig.tick));
    /* frozen order 4 is simply not removed: the error is bounded by its
     * 0.4 N m amplitude plus noise and the other blocks' errors */
    double during = fi_max_abs_err(&rig, 13000, 14500);
    long rec = fi_recovery_ticks(&rig, 15000, FI_BAND_NM, FI_HOLD_TICKS);
    fi_report(&rig, "order_over_nyquist", rec, LIMIT_RESETTLE, during, 12500, 14500,
              "speed_rad_s=900 window_ms=2000");
    TEST_ASSERT_TRUE(during < 1.0);
    TEST_ASSERT_TRUE(rec >= 0 && rec <= LIMIT_RESETTLE);
}

static void test_load_step_up_and_down(void)
{
    /* +10 N m in 5 ms at 12 s; and -10 N m from 13 N m at 12 s */
    profile_case("load_step_up",
                 "duration_s = 20\nload_torque_profile = 0:3, 12:3, 12.005:13\n", T0 + 5u, 0,
                 LIMIT_RESETTLE);
    profile_case("load_step_down",
                 "duration_s = 20\nload_torque_profile = 0:13, 12:13, 12.005:3\n", T0 + 5u, 0,
                 LIMIT_RESETTLE);
}

static void test_ripple_amplitude_change(void)
{
    /* a 1 N m motor order-2 line appears at 12 s on top of the existing one
     * (amplitude 1.0 -> about 1.6 N m, phase shifted) */
    fi_rig_init(&rig, "duration_s = 18\n");
    rig.fault.kind = FI_EXTRA_RIPPLE;
    rig.fault.start_tick = T0;
    rig.fault.end_tick = T0;
    rig.fault.amp_nm = 1.0;
    fi_rig_run(&rig, UINT64_MAX);
    assert_invariants();
    TEST_ASSERT_EQUAL_HEX16(0, fi_faults_in(&rig, 0, rig.tick));
    long rec = fi_recovery_ticks(&rig, T0, FI_BAND_NM, FI_HOLD_TICKS);
    char extra[48];
    snprintf(extra, sizeof extra, "extra_line_nm=%g", rig.fault.amp_nm);
    fi_report(&rig, "ripple_amplitude_step", rec, LIMIT_RESETTLE,
              fi_max_abs_err(&rig, T0, T0 + 1000u), 0, rig.tick, extra);
    TEST_ASSERT_TRUE(rec >= 0 && rec <= LIMIT_RESETTLE);
}

/* An effect the model lacks (issue 21): a 0.8 N m motor order 3 line that no
 * block models, above the 0.5 N m jump gate, all run long.  It is reported
 * (filter status UNMODELLED, counted for INFO UNMODELLED_STEPS), not absorbed:
 * the filtered error stays below the line's own RMS plus the noise floor x
 * 5 (the run without the line is the baseline case above), and the
 * correction never reaches its limit. */
#define UNDECLARED_LINE_NM 0.8
static void test_undeclared_line_is_reported_not_absorbed(void)
{
    fi_rig_init(&rig, "duration_s = 18\nripple = motor : 3 : 0.8 : 0.2\n");
    fi_rig_run(&rig, UINT64_MAX);
    assert_invariants();
    const uint32_t f = fi_faults_in(&rig, 0, rig.tick);
    const uint32_t unmodelled = rig.fw.counters.unmodelled_steps; /* INFO 49 */
    const uint32_t limited = rig.fw.counters.correction_limited;  /* INFO 50 */
    const double err = fi_rms_err(&rig, T0, rig.tick);
    const double own = UNDECLARED_LINE_NM / sqrt(2.0);
    char msg[160];
    snprintf(msg, sizeof msg, "undeclared 0.8 N m line: error RMS %.4f N m (its own RMS %.4f), "
             "%u ticks beyond the held gate, %u at the correction limit",
             err, own, (unsigned)unmodelled, (unsigned)limited);
    TEST_MESSAGE(msg);
    TEST_ASSERT_EQUAL_HEX32(0u, f); /* no fault: an effect the model lacks is a status */
    TEST_ASSERT_GREATER_THAN_UINT32(0u, unmodelled);
    TEST_ASSERT_EQUAL_UINT32(0u, limited);
    TEST_ASSERT_LESS_THAN_DOUBLE(own + 5.0 * 0.02, err);
}

int main(int argc, char **argv)
{
    if (UnityParseOptions(argc, argv) != 0) {
        return 1;
    }
    UNITY_BEGIN();
    RUN_TEST(test_undeclared_line_is_reported_not_absorbed);
    RUN_TEST(test_no_fault_baseline);
    RUN_TEST(test_adc_read_error_500ms);
    RUN_TEST(test_adc_stuck_at_rail_500ms);
    RUN_TEST(test_open_bridge_500ms);
    RUN_TEST(test_out_of_range_sample_100ms);
    RUN_TEST(test_single_wild_sample_inside_range);
    RUN_TEST(test_encoder_fault_200ms);
    RUN_TEST(test_encoder_glitch_one_tick);
    RUN_TEST(test_encoder_jump_detected);
    RUN_TEST(test_encoder_lost_counts_undetectable);
    RUN_TEST(test_direction_reversal);
    RUN_TEST(test_standstill_three_minutes);
    RUN_TEST(test_order_over_nyquist);
    RUN_TEST(test_load_step_up_and_down);
    RUN_TEST(test_ripple_amplitude_change);
    return UNITY_END();
}
