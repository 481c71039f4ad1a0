/* Host timing of the tick at its profile boundaries (docs/design/slow-torque.md,
 * "Cost"): the median time of hd_fw_isr on plain ticks, on ticks that import
 * a profile (boot, PROFILE_LOAD, restarts) and on ticks that take a
 * PROFILE_SAVE snapshot, measured in the same run on the mock HAL with the
 * recommended model (3 blocks + offset) and a 3-line profile.  A benchmark:
 * it prints numbers and ratios, it does not pass or fail. */
#define _POSIX_C_SOURCE 200809L
#include <stdio.h>
#include <stdlib.h>
#include <string.h>
#include <time.h>

#include "hal_mock.h"
#include "hd_fw.h"

#define REPS 2001

static hal_mock_t mock;
static hal_t hal;
static hd_fw_t fw;

static double now_ns(void)
{
    struct timespec ts;
    clock_gettime(CLOCK_MONOTONIC, &ts);
    return (double)ts.tv_sec * 1e9 + (double)ts.tv_nsec;
}

static int cmp(const void *a, const void *b)
{
    double x = *(const double *)a, y = *(const double *)b;
    return (x > y) - (x < y);
}

/* kind: 0 plain, 1 import before the step, 2 snapshot after it */
static double median_tick_ns(int kind)
{
    static double t[REPS];
    uint32_t motor = 12345u;
    for (int i = 0; i < REPS; i++) {
        motor += 37u;
        hal_mock_sample_t s;
        memset(&s, 0, sizeof s);
        s.adc.bridge_counts = 1000 + (i % 7);
        s.enc.motor_counts = motor;
        s.enc.output_counts = motor / 100u;
        s.enc.has_output = true;
        hal_mock_push_sample(&mock, &s);
        if (kind == 1) {
            fw.filter.import_pending = true;
        } else if (kind == 2) {
            fw.filter.snapshot_pending = true;
        }
        double t0 = now_ns();
        hd_fw_isr(&fw);
        t[i] = now_ns() - t0;
        hal_mock_tx_clear(&mock);
    }
    qsort(t, REPS, sizeof t[0], cmp);
    return t[REPS / 2];
}

int main(void)
{
    hal_mock_init(&mock);
    hal_mock_bind(&mock, &hal);
    hd_fw_config_t cfg;
    hd_fw_config_default(&cfg);
    cfg.telemetry_rate_hz = 0; /* the torque path only */
    if (hd_fw_init(&fw, &hal, &cfg) != HD_FW_OK) {
        fprintf(stderr, "init failed\n");
        return 1;
    }
    hd_kf_profile_t p = {3, {{HD_KF_LOCK_MOTOR, 2, 0.7f, -0.4f},
                             {HD_KF_LOCK_MOTOR, 4, 0.1f, 0.25f},
                             {HD_KF_LOCK_OUTPUT, 1, 0.3f, 0.2f}}, -1.0f};
    fw.bg.profile = p;
    double plain[3], imp[3], snap[3];
    for (int r = 0; r < 3; r++) { /* interleaved, three rounds */
        plain[r] = median_tick_ns(0);
        imp[r] = median_tick_ns(1);
        snap[r] = median_tick_ns(2);
    }
    qsort(plain, 3, sizeof plain[0], cmp);
    qsort(imp, 3, sizeof imp[0], cmp);
    qsort(snap, 3, sizeof snap[0], cmp);
    printf("tick_plain_ns = %.0f\n", plain[1]);
    printf("tick_import_ns = %.0f (x%.2f)\n", imp[1], imp[1] / plain[1]);
    printf("tick_snapshot_ns = %.0f (x%.2f)\n", snap[1], snap[1] / plain[1]);
    printf("profile_imports = %u\n", (unsigned)fw.counters.profile_imports);
    return 0;
}
