/*
 * hal/moteus's actuator on a mock bus: the stop on disable, the command as
 * one FD frame to 0x8000 | source << 8 | id with the feed-forward torque
 * i kt, and the status from replies (mode 1 = fault), other ids ignored.
 * The bytes themselves are checked against the moteus package
 * (test_moteus_frames.py).
 */
#include <math.h>
#include <string.h>

#include "hal_mock.h"
#include "hal_moteus.h"
#include "hd_record_store.h"
#include "unity.h"

void setUp(void) {}
void tearDown(void) {}

static hal_mock_t mock;
static hal_can_t bus;
static hal_moteus_t mo;
static hal_t hal;

static void push_reply(uint32_t id, uint8_t mode, uint8_t fault)
{
    hal_can_frame_t f = {0};
    f.id = id;
    f.flags = HAL_CAN_FLAG_EXT | HAL_CAN_FLAG_FD;
    const uint8_t r[] = {0x21, 0x00, mode, 0x23, 0x0D, 48, 35, fault};
    memcpy(f.data, r, sizeof r);
    f.len = sizeof r;
    TEST_ASSERT_EQUAL_INT(0, hal_mock_push_rx(&mock, &f));
}

static void test_actuator_on_a_mock_bus(void)
{
    hal_mock_init(&mock);
    hal_mock_bind_can(&mock, &bus);
    hal_moteus_init(&mo, &bus, 3u, 0u, 0.06f);
    hal = (hal_t){0};
    hal_moteus_bind(&mo, &hal);
    void *ctx = hal.actuator.ctx;
    TEST_ASSERT_EQUAL_INT(HAL_OK, hal.actuator.enable(ctx, true));
    TEST_ASSERT_EQUAL_UINT32(0u, hal_mock_tx_count(&mock)); /* the command enters the mode */
    TEST_ASSERT_EQUAL_INT(HAL_OK, hal.actuator.command_current(ctx, 2.0f));
    const hal_can_frame_t *c = hal_mock_tx(&mock, 0);
    TEST_ASSERT_EQUAL_HEX32(0x8003u, c->id);
    TEST_ASSERT_TRUE(c->flags & HAL_CAN_FLAG_FD);
    /* 01 00 0a | 0c 05 20 | position, velocity, feed-forward torque at 14..17 */
    TEST_ASSERT_EQUAL_FLOAT(2.0f * 0.06f, hd_le_get_f32(&c->data[14]));
    TEST_ASSERT_EQUAL_INT(HAL_ERR_RANGE, hal.actuator.command_current(ctx, INFINITY));
    TEST_ASSERT_EQUAL_INT(HAL_OK, hal.actuator.enable(ctx, false));
    const hal_can_frame_t *s = hal_mock_tx(&mock, 1);
    TEST_ASSERT_EQUAL_HEX8(0x01u, s->data[0]);
    TEST_ASSERT_EQUAL_HEX8(0x00u, s->data[2]); /* mode 0: stopped */
    hal_drive_status_t st;
    push_reply(3u << 8 | 0u, 10u, 0u);
    TEST_ASSERT_EQUAL_INT(HAL_OK, hal.actuator.status(ctx, &st));
    TEST_ASSERT_TRUE(st.enabled);
    TEST_ASSERT_FALSE(st.fault);
    TEST_ASSERT_FLOAT_WITHIN(1e-6, 24.0f, st.bus_voltage_v);
    push_reply(4u << 8 | 0u, 1u, 7u); /* another moteus: not ours */
    TEST_ASSERT_EQUAL_INT(HAL_OK, hal.actuator.status(ctx, &st));
    TEST_ASSERT_FALSE(st.fault);
    push_reply(3u << 8 | 0u, 1u, 33u);
    TEST_ASSERT_EQUAL_INT(HAL_OK, hal.actuator.status(ctx, &st));
    TEST_ASSERT_TRUE(st.fault);
    TEST_ASSERT_EQUAL_UINT32(33u, st.fault_code);
}

int main(int argc, char **argv)
{
    if (UnityParseOptions(argc, argv) != 0) {
        return 1;
    }
    UNITY_BEGIN();
    RUN_TEST(test_actuator_on_a_mock_bus);
    return UNITY_END();
}
