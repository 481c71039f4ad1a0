/* fi_rig: see fi_rig.h. */
#include "fi_rig.h"

#include <math.h>
#include <stdio.h>
#include <string.h>

#include "hd_config_text.h"
#include "hd_sim_scenario.h"
#include "rel_measured.h"
#include "unity.h"

/* The rig's joint and the expected-torque model the project's tool
 * identified for it (rig_identify.py): files in this folder, read once. */
static const char *rig_file(const char *name, char *buf, size_t cap)
{
    char path[512];
    snprintf(path, sizeof path, "%s/%s", HD_RIG_DIR, name);
    FILE *f = fopen(path, "rb");
    if (f == NULL) {
        TEST_FAIL_MESSAGE("cannot open a rig file (rig_joint.ini, rig_expected.cfg)");
    }
    size_t n = fread(buf, 1, cap - 1u, f);
    fclose(f);
    TEST_ASSERT_TRUE_MESSAGE(n < cap - 1u, "rig file too large");
    buf[n] = '\0';
    return buf;
}

/* ------------------------------------------------------------ the injector */

static bool in_window(const fi_rig_t *r)
{
    return r->tick >= r->fault.start_tick && r->tick < r->fault.end_tick;
}

static int inj_adc_read(void *ctx, hal_adc_sample_t *out)
{
    fi_rig_t *r = ctx;
    int rc = r->sim_hal.sensors.adc_read(r->sim_hal.sensors.ctx, out);
    if (rc != HAL_OK) {
        return rc; /* end of the scenario */
    }
    const hd_sim_sample_t *s = hal_sim_current(&r->sim);
    if (r->fault.kind == FI_EXTRA_RIPPLE && r->tick >= r->fault.start_tick) {
        /* a new motor order-2 line in the sensor, not in the truth */
        double extra_nm = r->fault.amp_nm * sin(2.0 * s->motor_angle_rad + 0.5);
        double counts = extra_nm / (r->nom.gain_nm_per_v * r->nom.adc_v_per_count);
        out->bridge_counts += (int32_t)lround(counts);
    }
    if (!in_window(r)) {
        return HAL_OK;
    }
    switch (r->fault.kind) {
    case FI_ADC_IO:
        return HAL_ERR_IO;
    case FI_OPEN_BRIDGE:
        out->bridge_counts = 32767;
        return HAL_ERR_FAULT;
    case FI_ADC_RAIL:
        out->bridge_counts = 32767;
        out->saturated = true;
        return HAL_OK;
    case FI_ADC_COUNTS:
        out->bridge_counts = r->fault.counts;
        return HAL_OK;
    default:
        return HAL_OK;
    }
}

static int inj_encoder_read(void *ctx, hal_encoder_sample_t *out)
{
    fi_rig_t *r = ctx;
    int rc = r->sim_hal.sensors.encoder_read(r->sim_hal.sensors.ctx, out);
    if (rc != HAL_OK) {
        return rc;
    }
    if (r->fault.kind == FI_ENC_JUMP && r->tick >= r->fault.start_tick) {
        out->motor_counts += (uint32_t)r->fault.counts;
    }
    if (!in_window(r)) {
        return HAL_OK;
    }
    if (r->fault.kind == FI_ENC_FAULT) {
        out->fault = true;
        out->motor_counts = 0xDEADBEEFu; /* garbage: must not be used */
    } else if (r->fault.kind == FI_ENC_SPIKE) {
        out->motor_counts += (uint32_t)r->fault.counts;
    }
    return HAL_OK;
}

/* ------------------------------------------------------- telemetry decoding */

static uint32_t u24le(const uint8_t *p)
{
    return (uint32_t)p[0] | ((uint32_t)p[1] << 8) | ((uint32_t)p[2] << 16);
}

/* Decodes by the byte layout of docs/reference/protocol.md (not with hd_can_proto):
 * 29-bit identifier 0x01D0TTNN, TT the frame type, NN the node. */
static void tx_hook(void *ctx, const hal_can_frame_t *f, uint64_t t_us)
{
    fi_rig_t *r = ctx;
    (void)t_us;
    const uint32_t node = hd_fw_config(&r->fw)->node_id;
    if ((f->flags & HAL_CAN_FLAG_EXT) == 0u || (f->id & 0x1FFF00FFu) != (0x01D00000u | node)) {
        return;
    }
    const uint32_t type = (f->id >> 8) & 0xFFu;
    if (type == 0x02u) {
        uint8_t seq = f->data[6];
        if (r->have_seq && (uint8_t)(seq - r->last_seq) != 1u) {
            r->seq_gaps += (uint8_t)(seq - r->last_seq) - 1u;
        }
        r->last_seq = seq;
        r->have_seq = true;
        r->telem_a++;
    } else if (type == 0x03u) {
        r->telem_faults_or |= u24le(&f->data[3]);
        r->telem_b++;
    } else if (type == 0x20u) {
        r->heartbeats++;
        r->last_hb_faults = u24le(&f->data[1]);
        r->hb_faults_or |= r->last_hb_faults;
        r->last_hb_calib_status = f->data[6] & 0x0Fu;
    } else if (type == 0x11u) {
        r->acks++;
        memcpy(r->last_ack, f->data, 8);
    }
}

/* ------------------------------------------------------------------ set-up */

void fi_rig_init(fi_rig_t *r, const char *extra)
{
    memset(r, 0, sizeof *r);
    static char text[4096];
    if (extra == NULL) {
        extra = "";
    }
    /* defaults for the keys a test may set (scalar keys may appear once) */
    static char joint[2048];
    snprintf(text, sizeof text, "%s%s%s%s", rig_file("rig_joint.ini", joint, sizeof joint),
             strstr(extra, "duration_s") ? "" : "duration_s = 8\n",
             strstr(extra, "load_torque_profile") ? "" : "load_torque_profile = 0:3\n", extra);
    hd_sim_scenario_t sc;
    hd_sim_scenario_default(&sc);
    char err[256];
    if (hd_sim_scenario_parse(&sc, text, "fi_rig", err, sizeof err) != 0) {
        TEST_FAIL_MESSAGE(err);
    }
    if (hal_sim_init(&r->sim, &sc, err, sizeof err) != 0) {
        TEST_FAIL_MESSAGE(err);
    }
    r->n_ticks = hal_sim_samples(&r->sim);
    TEST_ASSERT_TRUE(r->n_ticks <= FI_MAX_TICKS);
    hal_sim_bind(&r->sim, &r->sim_hal);
    hal_sim_nominal(&r->sim, &r->nom);

    hal_mock_init(&r->mock);
    r->mock.tx_store = false; /* the hook sees every frame; nothing is capped */
    r->mock.tx_hook = tx_hook;
    r->mock.tx_hook_ctx = r;
    hal_mock_bind(&r->mock, &r->hal); /* CAN and NVM from the mock */
    r->hal.name = "fi_rig";
    r->hal.sensors.ctx = r;
    r->hal.sensors.adc_read = inj_adc_read;
    r->hal.sensors.encoder_read = inj_encoder_read;
    r->hal.clock = r->sim_hal.clock; /* sample time: 1000 us per tick */

    /* the nominal calibration in NVM, as the host runner stores it */
    hd_calib_record_t rec;
    hd_calib_record_default(&rec);
    rec.gain_nm_per_v = (float)r->nom.gain_nm_per_v;
    rec.offset_v = (float)r->nom.offset_v;
    static uint8_t work[HD_STORE_IMAGE_MAX];
    hd_calib_storage_t st = hd_fw_store_io(&r->hal, work, sizeof work);
    TEST_ASSERT_EQUAL_INT(HD_RECORD_OK, hd_calib_store_save(&st, &rec));

    hd_fw_config_default(&r->cfg);
    r->cfg.adc_volts_per_count = (float)r->nom.adc_v_per_count;
    r->cfg.motor_cpr = r->nom.motor_cpr;
    r->cfg.gear_ratio = (float)r->nom.gear_ratio;
    /* No oracle: the expected torque is what `hdsense analyze` identified
     * from a commissioning run (rig_expected.cfg); the sensor constants
     * above are the datasheet's, as on a real joint.  The rig measures
     * recovery of what the filter learned online, so its output-locked
     * blocks learn (adaptive), unlike the operating default. */
    static char model[1024];
    rig_file("rig_expected.cfg", model, sizeof model);
    hd_cfgtxt_error_t cerr;
    TEST_ASSERT_EQUAL_INT_MESSAGE(HD_FW_OK, hd_config_text_parse(model, strlen(model), &r->cfg, &cerr),
                                  cerr.message);
    r->cfg.learning_mode = HD_FW_LEARN_ADAPTIVE;
    TEST_ASSERT_EQUAL_INT(HD_FW_OK, hd_fw_init(&r->fw, &r->hal, &r->cfg));
    r->fault.start_tick = UINT64_MAX;
    r->fault.end_tick = UINT64_MAX;
}

/* ---------------------------------------------------------------- running */

static void check_tick(fi_rig_t *r, const hd_fw_sample_t *s)
{
    const hd_fw_config_t *c = hd_fw_config(&r->fw);
    if (!isfinite(s->ripple_nm) || !isfinite(s->motor_velocity_rad_s) ||
        !isfinite(s->torque_expected_nm) || (s->valid && !isfinite(s->torque_filtered_nm))) {
        r->non_finite++;
        return;
    }
    /* physical bounds: a ripple estimate beyond the torque range, a filtered
     * torque beyond twice the range or a speed beyond 1.5 x the glitch limit
     * would mean the numbers have run away */
    if (fabsf(s->ripple_nm) > c->torque_limit_nm ||
        fabsf(s->motor_velocity_rad_s) > 1.5f * c->max_motor_speed_rad_s ||
        (s->valid && fabsf(s->torque_filtered_nm) > 2.0f * c->torque_limit_nm)) {
        r->out_of_bounds++;
    }
    if (!s->valid && s->faults == 0u) {
        r->invalid_unflagged++;
    }
    if (s->valid && fabs((double)s->torque_filtered_nm) > r->max_abs_filtered_nm) {
        r->max_abs_filtered_nm = fabs((double)s->torque_filtered_nm);
    }
}

uint64_t fi_rig_run(fi_rig_t *r, uint64_t n)
{
    uint64_t done = 0;
    while (done < n && r->tick < r->n_ticks) {
        uint32_t before = r->fw.counters.ticks;
        hd_fw_isr(&r->fw);
        hd_fw_background(&r->fw);
        if (r->fw.counters.ticks != before + 1u) {
            r->bad_steps++;
            break;
        }
        const hd_fw_sample_t *s = hd_fw_last_sample(&r->fw);
        check_tick(r, s);
        const hd_sim_sample_t *truth = hal_sim_current(&r->sim);
        r->err_nm[r->tick] = s->valid ? (float)((double)s->torque_filtered_nm - truth->torque_true_nm)
                                      : NAN;
        r->faults[r->tick] = s->faults;
        r->tick++;
        done++;
    }
    return done;
}

long fi_recovery_ticks(const fi_rig_t *r, uint64_t from_tick, double band_nm, uint64_t hold)
{
    uint64_t run = 0;
    for (uint64_t t = from_tick; t < r->tick; t++) {
        float e = r->err_nm[t];
        if (isfinite(e) && fabs((double)e) <= band_nm) {
            run++;
            if (run >= hold) {
                return (long)(t + 1u - hold - from_tick);
            }
        } else {
            run = 0;
        }
    }
    return -1;
}

double fi_max_abs_err(const fi_rig_t *r, uint64_t a, uint64_t b)
{
    double m = (double)NAN;
    for (uint64_t t = a; t < b && t < r->tick; t++) {
        float e = r->err_nm[t];
        if (isfinite(e) && !(fabs((double)e) <= m)) {
            m = fabs((double)e);
        }
    }
    return m;
}

double fi_rms_err(const fi_rig_t *r, uint64_t a, uint64_t b)
{
    double s = 0.0;
    uint64_t n = 0;
    for (uint64_t t = a; t < b && t < r->tick; t++) {
        float e = r->err_nm[t];
        if (isfinite(e)) {
            s += (double)e * (double)e;
            n++;
        }
    }
    return n > 0 ? sqrt(s / (double)n) : (double)NAN;
}

uint32_t fi_faults_in(const fi_rig_t *r, uint64_t a, uint64_t b)
{
    uint32_t f = 0;
    for (uint64_t t = a; t < b && t < r->tick; t++) {
        f |= r->faults[t];
    }
    return f;
}

void fi_push_cmd(fi_rig_t *r, const uint8_t data[8], uint8_t len, uint8_t flags, uint32_t id)
{
    hal_can_frame_t f;
    memset(&f, 0, sizeof f);
    f.id = id;
    f.len = len;
    f.flags = (uint8_t)(flags | (id > 0x7FFu ? HAL_CAN_FLAG_EXT : 0u)); /* 29-bit ids */
    memcpy(f.data, data, len <= 8u ? len : 8u);
    TEST_ASSERT_EQUAL_INT(0, hal_mock_push_rx(&r->mock, &f));
}

void fi_report(const fi_rig_t *r, const char *name, long recovery_ticks, long limit_ticks,
               double max_err_nm, uint64_t flag_from, uint64_t flag_to, const char *extra)
{
    char err[32] = "";
    if (isfinite(max_err_nm)) {
        snprintf(err, sizeof err, " max_err_nm=%.6g", max_err_nm);
    }
    rel_measured(name, "recovery_ticks=%ld limit_ticks=%ld faults=0x%x%s%s%s", recovery_ticks,
                 limit_ticks, (unsigned)fi_faults_in(r, flag_from, flag_to), err,
                 extra != NULL ? " " : "", extra != NULL ? extra : "");
}

void fi_report_setup(uint64_t fault_start_tick)
{
    rel_measured("rig", "band_nm=%g hold_ticks=%u fault_start_s=%g", FI_BAND_NM, FI_HOLD_TICKS,
                 (double)fault_start_tick / 1000.0);
}
