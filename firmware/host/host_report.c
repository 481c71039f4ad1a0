#include "host_report.h"

#include <ctype.h>
#include <math.h>
#include <signal.h>
#include <stdio.h>

#include "hd_can_proto.h"
#include "hd_fw_records.h"

void host_errors_add(host_errors_t *e, double t_s, double raw, double filt, double truth)
{
    if (!isfinite(raw) || !isfinite(filt) || !isfinite(truth)) {
        return;
    }
    double dr = raw - truth, df = filt - truth;
    e->n++;
    e->sum_raw2 += dr * dr;
    e->sum_filt2 += df * df;
    if (t_s < 1.0) {
        e->n_first++;
        e->sum_filt2_first += df * df;
    }
    if (t_s >= 1.0) {
        e->n_settled++;
        e->sum_raw2_settled += dr * dr;
        e->sum_filt2_settled += df * df;
    }
}

/* "fault_<name> = count" in the summary: the protocol's fault name, lower case. */
static void print_fault_count(unsigned bit, uint32_t count)
{
    const char *name = hd_can_fault_str(bit);
    printf("fault_");
    for (const char *c = name; *c != '\0'; c++) {
        putchar(tolower((unsigned char)*c));
    }
    printf(" = %u\n", (unsigned)count);
}

const char *host_signal_name(int sig)
{
    return sig == SIGINT ? "SIGINT" : (sig == SIGTERM ? "SIGTERM" : "a signal");
}

void host_print_summary(const host_summary_t *s)
{
    const host_options_t *o = s->o;
    const hd_fw_counters_t *c = hd_fw_counters(s->fw);
    hal_counters_t hc = {0};
    if (s->hal->can.counters != NULL) {
        s->hal->can.counters(s->hal->can.ctx, &hc);
    }
    printf("samples = %llu\n", (unsigned long long)c->ticks);
    printf("valid_samples = %llu\n", (unsigned long long)c->valid_samples);
    printf("mode = %s\n", o->realtime ? "realtime" : "fast");
    if (s->sig != 0) {
        printf("interrupted = %s\n", host_signal_name(s->sig));
    }
    printf("wall_time_s = %.3f\n", s->wall_s);
    printf("isr_mean_us = %.3f\n", s->tm->ticks ? s->tm->isr_sum_us / (double)s->tm->ticks : 0.0);
    printf("isr_max_us = %.3f\n", s->tm->isr_max_us);
    if (o->realtime) {
        printf("jitter_mean_us = %.3f\n", s->tm->ticks ? s->tm->jitter_sum_us / (double)s->tm->ticks : 0.0);
        printf("jitter_max_us = %.3f\n", s->tm->jitter_max_us);
        printf("overruns = %llu\n", (unsigned long long)s->tm->overruns);
        printf("missed_ticks = %llu\n", (unsigned long long)s->tm->missed_ticks);
    }
    printf("deadline_misses = %u\n", (unsigned)c->deadline_misses);
    printf("fault_ticks = %u\n", (unsigned)c->fault_ticks);
    for (unsigned b = 0; b < HD_FAULT_COUNT; b++) {
        if (c->by_fault[b] != 0u) {
            print_fault_count(b, c->by_fault[b]);
        }
    }
    printf("calib_status = %d\n", hd_fw_record_status(s->fw, HD_RECORD_KIND_CALIB));
    printf("profile_status = %d\n", hd_fw_record_status(s->fw, HD_RECORD_KIND_PROFILE));
    printf("profile_imports = %u\n", (unsigned)c->profile_imports);
    const hd_fw_config_t *fc = hd_fw_config(s->fw);
    printf("expected_model = J %g kg m^2, b %g N m s/rad, Fc %g N m (%s)\n",
           (double)fc->expected.inertia_kgm2, (double)fc->expected.viscous_nm_s_rad,
           (double)fc->expected.coulomb_nm, o->config != NULL ? "defaults + --config" :
           "defaults");
    printf("feedforward_frames_given = %llu\n", (unsigned long long)s->ff_frames);
    printf("feedforward_frames_taken = %u\n", (unsigned)c->feedforward_frames);
    printf("config_status = %d\n", hd_fw_record_status(s->fw, HD_RECORD_KIND_CONFIG));
    printf("truth = %s\n", s->have_truth ? "yes" : "no");
    printf("telemetry_periods = %u\n", (unsigned)c->telemetry_frames);
    printf("commands = %u\n", (unsigned)c->commands);
    printf("command_errors = %u\n", (unsigned)c->command_errors);
    printf("cmd_frames_given = %d\n", o->n_cmds);
    printf("can_tx_ok = %u\n", (unsigned)hc.can_tx_ok);
    printf("can_tx_dropped = %u\n", (unsigned)hc.can_tx_dropped);
    if (s->canlog_open) {
        printf("can_log = %s\n", o->can + 4);
        printf("can_log_frames = %llu\n", (unsigned long long)s->canlog_frames);
    }
    if (o->nvm_file != NULL) {
        printf("nvm_file = %s\n", o->nvm_file);
        printf("nvm_writes = %u\n", (unsigned)s->nvm_writes);
    }
    if (s->er->n > 0u) {
        printf("rms_error_raw_nm = %.4f\n", sqrt(s->er->sum_raw2 / (double)s->er->n));
        printf("rms_error_filtered_nm = %.4f\n", sqrt(s->er->sum_filt2 / (double)s->er->n));
    }
    if (s->er->n_first > 0u) {
        printf("rms_error_filtered_first_1s_nm = %.4f\n",
               sqrt(s->er->sum_filt2_first / (double)s->er->n_first));
    }
    if (s->er->n_settled > 0u) {
        printf("rms_error_raw_after_1s_nm = %.4f\n", sqrt(s->er->sum_raw2_settled / (double)s->er->n_settled));
        printf("rms_error_filtered_after_1s_nm = %.4f\n",
               sqrt(s->er->sum_filt2_settled / (double)s->er->n_settled));
    }
    if (s->replay_trailing_bytes != 0u) {
        printf("replay_trailing_bytes = %u\n", s->replay_trailing_bytes);
    }
}
