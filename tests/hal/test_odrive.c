/*
 * hal/odrive's actuator on a mock bus: what each call puts on the wire (the
 * command ids of ODrive's CAN Simple table, node << 5 | command, 11-bit) and
 * what the status makes of the ODrive's heartbeat.
 */
#include <math.h>
#include <string.h>

#include "hal_mock.h"
#include "hal_odrive.h"
#include "unity.h"

void setUp(void) {}
void tearDown(void) {}

static hal_mock_t mock;
static hal_can_t bus;
static hal_odrive_t od;
static hal_t hal;

static void start(void)
{
    hal_mock_init(&mock);
    hal_mock_bind_can(&mock, &bus);
    hal_odrive_init(&od, &bus, 3u, 0.06f);
    hal = (hal_t){0};
    hal_odrive_bind(&od, &hal);
}

static float f32_at(const hal_can_frame_t *f)
{
    float v;
    uint32_t u = (uint32_t)f->data[0] | (uint32_t)f->data[1] << 8 | (uint32_t)f->data[2] << 16 |
                 (uint32_t)f->data[3] << 24;
    memcpy(&v, &u, sizeof v);
    return v;
}

static void test_enable_command_disable_on_the_wire(void)
{
    start();
    TEST_ASSERT_EQUAL_INT(HAL_OK, hal.actuator.enable(hal.actuator.ctx, true));
    TEST_ASSERT_EQUAL_UINT32(3u, hal_mock_tx_count(&mock));
    TEST_ASSERT_EQUAL_HEX32(3u << 5 | 0x18u, hal_mock_tx(&mock, 0)->id); /* Clear_Errors */
    TEST_ASSERT_EQUAL_HEX32(3u << 5 | 0x0Bu, hal_mock_tx(&mock, 1)->id); /* Set_Controller_Mode */
    const hal_can_frame_t *st = hal_mock_tx(&mock, 2);
    TEST_ASSERT_EQUAL_HEX32(3u << 5 | 0x07u, st->id);                   /* Set_Axis_State */
    TEST_ASSERT_EQUAL_UINT8(8u, st->data[0]);                           /* CLOSED_LOOP_CONTROL */
    TEST_ASSERT_EQUAL_UINT8(0u, st->flags & HAL_CAN_FLAG_EXT);
    TEST_ASSERT_EQUAL_INT(HAL_OK, hal.actuator.command_current(hal.actuator.ctx, 2.5f));
    const hal_can_frame_t *tq = hal_mock_tx(&mock, 3);
    TEST_ASSERT_EQUAL_HEX32(3u << 5 | 0x0Eu, tq->id);                   /* Set_Input_Torque */
    TEST_ASSERT_EQUAL_FLOAT(2.5f * 0.06f, f32_at(tq));                  /* motor N m = i kt */
    TEST_ASSERT_EQUAL_INT(HAL_ERR_RANGE, hal.actuator.command_current(hal.actuator.ctx, NAN));
    TEST_ASSERT_EQUAL_UINT32(4u, hal_mock_tx_count(&mock));             /* nothing sent */
    TEST_ASSERT_EQUAL_INT(HAL_OK, hal.actuator.enable(hal.actuator.ctx, false));
    TEST_ASSERT_EQUAL_UINT8(1u, hal_mock_tx(&mock, 4)->data[0]);         /* IDLE */
}

static void push_heartbeat(uint32_t err, uint8_t state)
{
    hal_can_frame_t f = {0};
    f.id = 3u << 5 | 0x01u;
    f.len = 8u;
    f.data[0] = (uint8_t)err;
    f.data[1] = (uint8_t)(err >> 8);
    f.data[2] = (uint8_t)(err >> 16);
    f.data[3] = (uint8_t)(err >> 24);
    f.data[4] = state;
    TEST_ASSERT_EQUAL_INT(0, hal_mock_push_rx(&mock, &f));
}

static void test_status_from_the_heartbeat(void)
{
    start();
    hal_drive_status_t s;
    TEST_ASSERT_EQUAL_INT(HAL_OK, hal.actuator.status(hal.actuator.ctx, &s));
    TEST_ASSERT_FALSE(s.fault);
    TEST_ASSERT_EQUAL_UINT32(UINT32_MAX, s.age_ticks); /* never heard */
    push_heartbeat(0u, 8u);
    TEST_ASSERT_EQUAL_INT(HAL_OK, hal.actuator.status(hal.actuator.ctx, &s));
    TEST_ASSERT_TRUE(s.enabled);
    TEST_ASSERT_FALSE(s.fault);
    TEST_ASSERT_EQUAL_UINT32(0u, s.age_ticks);
    push_heartbeat(0x00000800u, 1u); /* an axis error, back to IDLE */
    TEST_ASSERT_EQUAL_INT(HAL_OK, hal.actuator.status(hal.actuator.ctx, &s));
    TEST_ASSERT_TRUE(s.fault);
    TEST_ASSERT_FALSE(s.enabled);
    TEST_ASSERT_EQUAL_HEX32(0x800u, s.fault_code);
    /* another node's heartbeat is not ours */
    hal_can_frame_t other = {0};
    other.id = 4u << 5 | 0x01u;
    other.len = 8u;
    hal_mock_push_rx(&mock, &other);
    push_heartbeat(0u, 8u);
    TEST_ASSERT_EQUAL_INT(HAL_OK, hal.actuator.status(hal.actuator.ctx, &s));
    TEST_ASSERT_FALSE(s.fault);
    TEST_ASSERT_TRUE(s.enabled);
}

int main(int argc, char **argv)
{
    if (UnityParseOptions(argc, argv) != 0) {
        return 1;
    }
    UNITY_BEGIN();
    RUN_TEST(test_enable_command_disable_on_the_wire);
    RUN_TEST(test_status_from_the_heartbeat);
    return UNITY_END();
}
