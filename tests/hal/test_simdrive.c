/*
 * hal_simdrive through its hal_actuator_t against closed forms: a current
 * step commanded at tick 0 reaches the current loop one tick late, then
 * rises as a first-order lag of time constant 1 / (2 pi f), so the motor
 * torque held over interval n >= 1 is the lag's mean over it,
 *   T_n = kt (1 + e) I [1 - exp(-w (n-1) ts) (1 - exp(-w ts)) / (w ts)],
 * and 0 over interval 0.  Saturation, disable, a fault and a non-finite
 * command each have their defined result.
 */
#include <math.h>

#include "hal_simdrive.h"
#include "unity.h"

#define PI_D 3.14159265358979323846

void setUp(void) {}
void tearDown(void) {}

static hal_simdrive_t drive;
static hal_t hal;

static void start(double kt_error, double bandwidth_hz)
{
    hal_simdrive_config_t cfg;
    hal_simdrive_default(&cfg);
    cfg.kt_error = kt_error;
    cfg.bandwidth_hz = bandwidth_hz;
    TEST_ASSERT_EQUAL_INT(0, hal_simdrive_init(&drive, &cfg));
    hal = (hal_t){0};
    hal_simdrive_bind(&drive, &hal);
    TEST_ASSERT_EQUAL_INT(HAL_OK, hal.actuator.enable(hal.actuator.ctx, true));
}

static void test_step_is_delayed_first_order_lag(void)
{
    const double kt_error = 0.07, f = 200.0, amps = 3.0;
    start(kt_error, f);
    const double w = 2.0 * PI_D * f, ts = drive.cfg.ts_s;
    const double kt_true = drive.cfg.kt_nm_per_a * (1.0 + kt_error);
    double worst = 0.0;
    for (int n = 0; n < 20; n++) {
        if (n == 0) {
            TEST_ASSERT_EQUAL_INT(HAL_OK, hal.actuator.command_current(hal.actuator.ctx, (float)amps));
        }
        const double t = hal_simdrive_tick(&drive);
        const double expect =
            n == 0 ? 0.0
                   : kt_true * amps * (1.0 - exp(-w * (n - 1) * ts) * (1.0 - exp(-w * ts)) / (w * ts));
        worst = fmax(worst, fabs(t - expect));
    }
    TEST_ASSERT_DOUBLE_WITHIN(1e-12, 0.0, worst);
    hal_drive_status_t st;
    TEST_ASSERT_EQUAL_INT(HAL_OK, hal.actuator.status(hal.actuator.ctx, &st));
    TEST_ASSERT_TRUE(st.enabled);
    TEST_ASSERT_FALSE(st.fault);
    TEST_ASSERT_FLOAT_WITHIN(1e-6, amps * (1.0 - exp(-w * 19 * ts)), st.current_a);
    TEST_ASSERT_FLOAT_WITHIN(1e-6, 24.0, st.bus_voltage_v);
}

static void test_saturation_disable_fault_nonfinite(void)
{
    start(0.0, 1500.0);
    void *ctx = hal.actuator.ctx;
    TEST_ASSERT_EQUAL_INT(HAL_OK, hal.actuator.command_current(ctx, 100.0f));
    double t = 0.0;
    for (int n = 0; n < 50; n++) {
        t = hal_simdrive_tick(&drive);
    }
    TEST_ASSERT_DOUBLE_WITHIN(1e-9, drive.cfg.kt_nm_per_a * drive.cfg.current_limit_a, t);
    /* a non-finite command is refused and the last one held */
    TEST_ASSERT_EQUAL_INT(HAL_ERR_RANGE, hal.actuator.command_current(ctx, NAN));
    TEST_ASSERT_DOUBLE_WITHIN(1e-9, t, hal_simdrive_tick(&drive));
    /* disabled: no torque at once */
    TEST_ASSERT_EQUAL_INT(HAL_OK, hal.actuator.enable(ctx, false));
    TEST_ASSERT_EQUAL_FLOAT(0.0f, (float)hal_simdrive_tick(&drive));
    /* a fault: no torque, reported, cannot be enabled until cleared */
    TEST_ASSERT_EQUAL_INT(HAL_OK, hal.actuator.enable(ctx, true));
    hal_simdrive_set_fault(&drive, true, 0x42u);
    TEST_ASSERT_EQUAL_FLOAT(0.0f, (float)hal_simdrive_tick(&drive));
    hal_drive_status_t st;
    TEST_ASSERT_EQUAL_INT(HAL_OK, hal.actuator.status(ctx, &st));
    TEST_ASSERT_TRUE(st.fault);
    TEST_ASSERT_FALSE(st.enabled);
    TEST_ASSERT_EQUAL_UINT32(0x42u, st.fault_code);
    TEST_ASSERT_EQUAL_INT(HAL_ERR_FAULT, hal.actuator.enable(ctx, true));
    hal_simdrive_set_fault(&drive, false, 0u);
    TEST_ASSERT_EQUAL_INT(HAL_OK, hal.actuator.enable(ctx, true));
}

static void test_bad_config_refused(void)
{
    hal_simdrive_config_t cfg;
    hal_simdrive_default(&cfg);
    cfg.bandwidth_hz = 0.0;
    TEST_ASSERT_EQUAL_INT(-1, hal_simdrive_init(&drive, &cfg));
    hal_simdrive_default(&cfg);
    cfg.kt_error = NAN;
    TEST_ASSERT_EQUAL_INT(-1, hal_simdrive_init(&drive, &cfg));
}

int main(int argc, char **argv)
{
    if (UnityParseOptions(argc, argv) != 0) {
        return 1;
    }
    UNITY_BEGIN();
    RUN_TEST(test_step_is_delayed_first_order_lag);
    RUN_TEST(test_saturation_disable_fault_nonfinite);
    RUN_TEST(test_bad_config_refused);
    return UNITY_END();
}
