/*
 * hd_pipeline_run over arrays must give exactly the same numbers (bit for
 * bit) as hd_pipeline_step called per sample, every output pointer may be
 * NULL, and feedforward NULL means 0.  Also: init error codes.
 */
#include <math.h>
#include <stdio.h>
#include <string.h>

#include "hd_pipeline.h"
#include "test_util.h"
#include "unity.h"

#define TS_S 1e-3f
#define N_SAMPLES 4000

void setUp(void) {}
void tearDown(void) {}

static float g_meas[N_SAMPLES], g_dm[N_SAMPLES], g_do[N_SAMPLES], g_ff[N_SAMPLES];
static float g_ff_var[N_SAMPLES]; /* the feed-forward's error variance: a lag's */

static void make_inputs(void)
{
    tu_rng_t r;
    tu_rng_seed(&r, 2024u);
    double am = 0.0;
    for (int k = 0; k < N_SAMPLES; k++) {
        double t = k * 1e-3;
        double w = 150.0 * sin(2.0 * TU_PI * 0.4 * t) + (k > 3000 ? 900.0 : 0.0); /* reversal, over-Nyquist */
        double d = w * 1e-3;
        am += d;
        g_dm[k] = (float)d;
        g_do[k] = (float)(d / 100.0);
        g_ff[k] = (float)(2.0 * sin(2.0 * TU_PI * 1.0 * t));
        g_ff_var[k] = (float)pow(0.03 * 2.0 * 2.0 * TU_PI * cos(2.0 * TU_PI * t), 2.0);
        g_meas[k] = (float)(3.0 + (double)g_ff[k] + cos(2.0 * am) + 0.3 * cos(4.0 * am) + 0.02 * tu_gauss(&r));
    }
    g_meas[1234] = NAN; /* a bad sample on the way */
}

static void init_pipe(hd_pipeline_t *p)
{
    hd_kf_config_t kc;
    hd_expected_config_t ec;
    hd_kf_config_paper(&kc, TS_S, true);
    kc.offset_enabled = 1;
    hd_expected_config_default(&ec);
    ec.inertia_kgm2 = 0.05f;
    ec.viscous_nm_s_rad = 0.3f;
    ec.coulomb_nm = 0.5f;
    TEST_ASSERT_EQUAL_INT(0, hd_pipeline_init(p, &kc, &ec, 20.0f));
}

/* Bitwise equality of the evolving state (field by field: struct padding is
 * not part of the state). */
static int same_bits(float a, float b) { return memcmp(&a, &b, sizeof(a)) == 0; }
static void assert_same_state(const hd_pipeline_t *a, const hd_pipeline_t *b, const char *what)
{
    unsigned n = hd_kf_state_count(&a->kf);
    TEST_ASSERT_EQUAL_UINT_MESSAGE(n, hd_kf_state_count(&b->kf), what);
    for (unsigned i = 0; i < n; i++) {
        TEST_ASSERT_TRUE_MESSAGE(same_bits(hd_kf_state(&a->kf, i), hd_kf_state(&b->kf, i)), what);
        for (unsigned j = 0; j < n; j++)
            TEST_ASSERT_TRUE_MESSAGE(same_bits(hd_kf_cov(&a->kf, i, j), hd_kf_cov(&b->kf, i, j)), what);
    }
    TEST_ASSERT_EQUAL_UINT32_MESSAGE(a->kf.frozen_mask, b->kf.frozen_mask, what);
    TEST_ASSERT_EQUAL_UINT32_MESSAGE(a->kf.status_sticky, b->kf.status_sticky, what);
    TEST_ASSERT_EQUAL_UINT32_MESSAGE(a->kf.reset_count, b->kf.reset_count, what);
    TEST_ASSERT_EQUAL_UINT32_MESSAGE(a->kf.bad_input_count, b->kf.bad_input_count, what);
    TEST_ASSERT_TRUE_MESSAGE(same_bits(a->output_track.err_rad, b->output_track.err_rad), what);
    TEST_ASSERT_TRUE_MESSAGE(same_bits(a->output_track.vel_rad_s, b->output_track.vel_rad_s), what);
    TEST_ASSERT_TRUE_MESSAGE(same_bits(a->output_track.acc_rad_s2, b->output_track.acc_rad_s2), what);
    TEST_ASSERT_TRUE_MESSAGE(same_bits(a->torque_expected_nm, b->torque_expected_nm), what);
}

typedef struct {
    float filtered[N_SAMPLES], ripple[N_SAMPLES], offset[N_SAMPLES], innov[N_SAMPLES];
    float innov_var[N_SAMPLES], texp[N_SAMPLES], vel[N_SAMPLES];
    float amp[N_SAMPLES * HD_KF_MAX_BLOCKS];
    unsigned status[N_SAMPLES];
} outs_t;

static outs_t g_step, g_run;

static void test_run_equals_step_bitwise(void)
{
    static hd_pipeline_t ps, pr;
    make_inputs();
    init_pipe(&ps);
    init_pipe(&pr);
    for (int k = 0; k < N_SAMPLES; k++) {
        hd_kf_output_t o;
        /* amplitude of the prediction used at this sample (the blocks are
         * all enabled: block b is states 2b, 2b+1) */
        float prior_amp[3];
        for (unsigned b = 0; b < 3u; b++) {
            const float x1 = hd_kf_state(&ps.kf, 2u * b), x2 = hd_kf_state(&ps.kf, 2u * b + 1u);
            prior_amp[b] = sqrtf(x1 * x1 + x2 * x2);
        }
        hd_pipeline_step(&ps, g_meas[k], g_dm[k], g_do[k], g_ff[k], g_ff_var[k], &o);
        g_step.filtered[k] = o.torque_filtered_nm;
        g_step.ripple[k] = o.ripple_nm;
        g_step.offset[k] = o.offset_nm;
        g_step.innov[k] = o.innovation_nm;
        g_step.innov_var[k] = o.innovation_var_nm2;
        g_step.texp[k] = ps.torque_expected_nm;
        g_step.vel[k] = ps.output_track.vel_rad_s;
        for (unsigned b = 0; b < HD_KF_MAX_BLOCKS; b++) {
            /* at the step's row entry: 1 (no load coefficient), 0 when frozen */
            const int frozen = (o.frozen_mask >> b) & 1u;
            g_step.amp[k * HD_KF_MAX_BLOCKS + b] = (b < 3u && !frozen) ? prior_amp[b] : 0.0f;
        }
        g_step.status[k] = o.status;
    }
    memset(&g_run, 0x5A, sizeof(g_run));
    hd_pipeline_io_t io = {N_SAMPLES, g_meas, g_dm, g_do, g_ff, g_ff_var,
                           g_run.filtered, g_run.ripple, g_run.offset, g_run.innov,
                           g_run.innov_var, g_run.texp, g_run.vel, g_run.amp, g_run.status,
                           NULL, NULL, NULL, NULL};
    hd_pipeline_run(&pr, &io);
    TEST_ASSERT_EQUAL_MEMORY_MESSAGE(g_step.filtered, g_run.filtered, sizeof(g_run.filtered), "filtered");
    TEST_ASSERT_EQUAL_MEMORY_MESSAGE(g_step.ripple, g_run.ripple, sizeof(g_run.ripple), "ripple");
    TEST_ASSERT_EQUAL_MEMORY_MESSAGE(g_step.offset, g_run.offset, sizeof(g_run.offset), "offset");
    TEST_ASSERT_EQUAL_MEMORY_MESSAGE(g_step.innov, g_run.innov, sizeof(g_run.innov), "innovation");
    TEST_ASSERT_EQUAL_MEMORY_MESSAGE(g_step.innov_var, g_run.innov_var, sizeof(g_run.innov_var), "S");
    TEST_ASSERT_EQUAL_MEMORY_MESSAGE(g_step.texp, g_run.texp, sizeof(g_run.texp), "T_exp");
    TEST_ASSERT_EQUAL_MEMORY_MESSAGE(g_step.vel, g_run.vel, sizeof(g_run.vel), "output velocity");
    TEST_ASSERT_EQUAL_MEMORY_MESSAGE(g_step.amp, g_run.amp, sizeof(g_run.amp), "amplitudes");
    TEST_ASSERT_EQUAL_MEMORY_MESSAGE(g_step.status, g_run.status, sizeof(g_run.status), "status");
    assert_same_state(&ps, &pr, "final pipeline state");
    /* the run exercised what it claims to */
    TEST_ASSERT_TRUE(g_run.status[1234] & HD_KF_STATUS_BAD_INPUT);
    TEST_ASSERT_TRUE(g_run.status[N_SAMPLES - 1] & HD_KF_STATUS_FROZEN);
    TEST_ASSERT_TRUE(fabs((double)g_run.texp[500]) > 0.0);
    TEST_ASSERT_TRUE(g_run.amp[(N_SAMPLES - 1) * HD_KF_MAX_BLOCKS] > 0.1f);
}

/* NULL outputs: the state evolves identically, the given outputs match. */
static void test_run_null_outputs_and_null_feedforward(void)
{
    static hd_pipeline_t pa, pb, pc;
    static float ff0[N_SAMPLES];
    static float filt_a[N_SAMPLES], filt_b[N_SAMPLES];
    make_inputs();
    init_pipe(&pa);
    init_pipe(&pb);
    init_pipe(&pc);
    memset(ff0, 0, sizeof(ff0));
    hd_pipeline_io_t all_null = {N_SAMPLES, g_meas, g_dm, g_do, g_ff, g_ff_var,
                                 NULL, NULL, NULL, NULL, NULL, NULL, NULL, NULL, NULL,
                                 NULL, NULL, NULL, NULL};
    hd_pipeline_run(&pa, &all_null);
    hd_pipeline_io_t one = all_null;
    one.torque_filtered_nm = filt_a;
    hd_pipeline_run(&pb, &one);
    assert_same_state(&pa, &pb, "state with NULL outputs");
    TEST_ASSERT_EQUAL_MEMORY(g_step.filtered, filt_a, sizeof(filt_a)); /* from the previous test */

    /* feedforward and its variance NULL == zeros */
    static hd_pipeline_t pd;
    init_pipe(&pd);
    hd_pipeline_io_t zf = all_null;
    zf.feedforward_nm = ff0;
    zf.feedforward_var_nm2 = ff0;
    zf.torque_filtered_nm = filt_a;
    hd_pipeline_run(&pc, &zf);
    hd_pipeline_io_t nf = all_null;
    nf.feedforward_nm = NULL;
    nf.feedforward_var_nm2 = NULL;
    nf.torque_filtered_nm = filt_b;
    hd_pipeline_run(&pd, &nf);
    TEST_ASSERT_EQUAL_MEMORY(filt_a, filt_b, sizeof(filt_a));
    assert_same_state(&pc, &pd, "NULL feedforward");

    /* n = 0 touches nothing */
    hd_pipeline_t before = pd;
    hd_pipeline_io_t empty = all_null;
    empty.n = 0;
    hd_pipeline_run(&pd, &empty);
    assert_same_state(&before, &pd, "n = 0");
}

/* Running in two chunks equals running in one. */
static void test_run_chunked_equals_whole(void)
{
    static hd_pipeline_t pa, pb;
    static float fa[N_SAMPLES], fb[N_SAMPLES];
    make_inputs();
    init_pipe(&pa);
    init_pipe(&pb);
    hd_pipeline_io_t whole = {N_SAMPLES, g_meas, g_dm, g_do, g_ff, NULL, fa,
                              NULL, NULL, NULL, NULL, NULL, NULL, NULL, NULL,
                              NULL, NULL, NULL, NULL};
    hd_pipeline_run(&pa, &whole);
    size_t h = 1777;
    hd_pipeline_io_t c1 = {h, g_meas, g_dm, g_do, g_ff, NULL, fb, NULL, NULL, NULL, NULL, NULL,
                           NULL, NULL, NULL, NULL, NULL, NULL, NULL};
    hd_pipeline_io_t c2 = {N_SAMPLES - h, g_meas + h, g_dm + h, g_do + h, g_ff + h, NULL, fb + h,
                           NULL, NULL, NULL, NULL, NULL, NULL, NULL, NULL, NULL, NULL, NULL, NULL};
    hd_pipeline_run(&pb, &c1);
    hd_pipeline_run(&pb, &c2);
    TEST_ASSERT_EQUAL_MEMORY(fa, fb, sizeof(fa));
    assert_same_state(&pa, &pb, "chunked");
}

/* The feed-forward's variance reaches the filter as R + v: from one state,
 * a step given v and the same step given 0 differ in S = C P C' + R + v by
 * exactly v (float rounding). */
static void test_feedforward_variance_adds_to_r(void)
{
    static hd_pipeline_t p, q;
    make_inputs();
    init_pipe(&p);
    unsigned checked = 0;
    for (int k = 0; k < N_SAMPLES; k++) {
        hd_kf_output_t op, oq;
        if (k % 701 == 350) {
            q = p;
            const float v = 0.5f + (float)checked;
            hd_pipeline_step(&q, g_meas[k], g_dm[k], g_do[k], g_ff[k], 0.0f, &oq);
            hd_pipeline_step(&p, g_meas[k], g_dm[k], g_do[k], g_ff[k], v, &op);
            TEST_ASSERT_FLOAT_WITHIN(1e-5f * op.innovation_var_nm2, v,
                                     op.innovation_var_nm2 - oq.innovation_var_nm2);
            checked++;
        } else {
            hd_pipeline_step(&p, g_meas[k], g_dm[k], g_do[k], g_ff[k], 0.0f, &op);
        }
    }
    TEST_ASSERT_TRUE(checked >= 5u);
}

static void test_pipeline_init_errors(void)
{
    static hd_pipeline_t p;
    hd_kf_config_t kc;
    hd_expected_config_t ec;
    hd_kf_config_paper(&kc, TS_S, false);
    hd_expected_config_default(&ec);
    TEST_ASSERT_EQUAL_INT(0, hd_pipeline_init(&p, &kc, &ec, 20.0f));
    TEST_ASSERT_EQUAL_INT(HD_KF_ERR_TRACK_BANDWIDTH, hd_pipeline_init(&p, &kc, &ec, 0.0f));
    TEST_ASSERT_EQUAL_INT(HD_KF_ERR_TRACK_BANDWIDTH, hd_pipeline_init(&p, &kc, &ec, NAN));
    TEST_ASSERT_EQUAL_INT(HD_KF_ERR_TRACK_BANDWIDTH,
                          hd_pipeline_init(&p, &kc, &ec, 1000.0f)); /* w ts > 0.5 */
    ec.coulomb_vel_eps_rad_s = 0.0f;
    TEST_ASSERT_EQUAL_INT(HD_KF_ERR_EXPECTED_CONFIG, hd_pipeline_init(&p, &kc, &ec, 20.0f));
    TEST_ASSERT_EQUAL_INT(HD_KF_ERR_NULL, hd_pipeline_init(&p, &kc, NULL, 20.0f));
    hd_expected_config_default(&ec);
    kc.r_nm2 = -1.0f;
    TEST_ASSERT_EQUAL_INT(HD_KF_ERR_NOISE, hd_pipeline_init(&p, &kc, &ec, 20.0f));
    hd_kf_config_paper(&kc, TS_S, false);
    kc.ts_s = 0.0f;
    TEST_ASSERT_EQUAL_INT(HD_KF_ERR_TS, hd_pipeline_init(&p, &kc, &ec, 20.0f));
}

int main(int argc, char **argv)
{
    if (UnityParseOptions(argc, argv) != 0) {
        return 1;
    }
    UNITY_BEGIN();
    RUN_TEST(test_run_equals_step_bitwise);
    RUN_TEST(test_run_null_outputs_and_null_feedforward);
    RUN_TEST(test_run_chunked_equals_whole);
    RUN_TEST(test_feedforward_variance_adds_to_r);
    RUN_TEST(test_pipeline_init_errors);
    return UNITY_END();
}
