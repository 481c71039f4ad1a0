/*
 * bxCAN driver (firmware/board/stm32f4/stm32f4_can.c) against the register
 * model (model_can.c): bit timing against a brute-force search over every
 * prescaler/BS1/BS2 and against published register values, the mode
 * handshakes, acceptance filtering, transmit mailboxes + software queue and
 * their order, the receive FIFO, bus-off recovery and the error counters.
 */
#include <stddef.h>
#include <string.h>

#include "model_can.h"
#include "stm32f4_can.h"
#include "unity.h"

#define POLLS 1000u

static can_model_t g_model;
static stm32_can_drv_t g_drv;

void setUp(void)
{
    reg_model_reset();
    can_model_init(&g_model);
    memset(&g_drv, 0, sizeof g_drv);
}

void tearDown(void)
{
}

static stm32_can_config_t config(uint32_t pclk, uint32_t bitrate)
{
    stm32_can_config_t c = {.can = &g_model.regs, .pclk1_hz = pclk, .bitrate = bitrate,
                            .ready_polls = POLLS, .loopback = false};
    return c;
}

static void start(void)
{
    stm32_can_config_t c = config(42000000u, 1000000u);
    TEST_ASSERT_EQUAL_INT(HAL_OK, stm32_can_init(&g_drv, &c));
    TEST_ASSERT_EQUAL_INT(CAN_MODE_NORMAL, g_model.mode);
}

static hal_can_frame_t frame(uint32_t id, uint8_t first)
{
    hal_can_frame_t f;
    memset(&f, 0, sizeof f);
    f.id = id;
    f.len = 8u;
    for (uint8_t i = 0; i < 8u; i++) {
        f.data[i] = (uint8_t)(first + i);
    }
    return f;
}

static void test_register_offsets_match_rm0090(void)
{
    TEST_ASSERT_EQUAL_UINT(0x000u, offsetof(stm32_can_t, MCR));
    TEST_ASSERT_EQUAL_UINT(0x008u, offsetof(stm32_can_t, TSR));
    TEST_ASSERT_EQUAL_UINT(0x00Cu, offsetof(stm32_can_t, RF0R));
    TEST_ASSERT_EQUAL_UINT(0x018u, offsetof(stm32_can_t, ESR));
    TEST_ASSERT_EQUAL_UINT(0x01Cu, offsetof(stm32_can_t, BTR));
    TEST_ASSERT_EQUAL_UINT(0x180u, offsetof(stm32_can_t, TX[0].TIR));
    TEST_ASSERT_EQUAL_UINT(0x1A4u, offsetof(stm32_can_t, TX[2].TDTR));
    TEST_ASSERT_EQUAL_UINT(0x1B0u, offsetof(stm32_can_t, RX[0].RIR));
    TEST_ASSERT_EQUAL_UINT(0x1CCu, offsetof(stm32_can_t, RX[1].RDHR));
    TEST_ASSERT_EQUAL_UINT(0x200u, offsetof(stm32_can_t, FMR));
    TEST_ASSERT_EQUAL_UINT(0x20Cu, offsetof(stm32_can_t, FS1R));
    TEST_ASSERT_EQUAL_UINT(0x214u, offsetof(stm32_can_t, FFA1R));
    TEST_ASSERT_EQUAL_UINT(0x21Cu, offsetof(stm32_can_t, FA1R));
    TEST_ASSERT_EQUAL_UINT(0x240u, offsetof(stm32_can_t, FR[0][0]));
    TEST_ASSERT_EQUAL_UINT(0x31Cu, offsetof(stm32_can_t, FR[27][1]));
}

/* Independent reference: every (prescaler, BS1, BS2) of the BTR fields
 * with at least 8 quanta that gives the bit rate exactly; the best sample
 * point error (|sp - 87.5 %|) and the smallest prescaler reaching it. */
typedef struct {
    int found;
    double best_err;
    unsigned best_brp;
} brute_t;

static brute_t brute_force(unsigned long pclk, unsigned long bitrate)
{
    brute_t b = {0, 1.0, 0};
    for (unsigned brp = 1; brp <= 1024; brp++) {
        for (unsigned bs1 = 1; bs1 <= 16; bs1++) {
            for (unsigned bs2 = 1; bs2 <= 8; bs2++) {
                unsigned tq = 1 + bs1 + bs2;
                if (tq < 8 || (unsigned long long)brp * tq * bitrate != pclk) {
                    continue;
                }
                double err = (double)(1 + bs1) / tq - 0.875;
                err = err < 0 ? -err : err;
                /* brp ascends: the first to reach the best error is the smallest */
                if (!b.found || err < b.best_err - 1e-12) {
                    b.found = 1;
                    b.best_err = err;
                    b.best_brp = brp;
                }
            }
        }
    }
    return b;
}

static void test_bit_timing_is_the_best_exact_setting(void)
{
    const unsigned long clocks[] = {42000000ul, 45000000ul, 16000000ul, 48000000ul, 36000000ul,
                                    30000000ul, 50000000ul};
    const unsigned long rates[] = {1000000ul, 500000ul, 250000ul, 125000ul, 800000ul};
    int cases = 0;
    for (size_t c = 0; c < sizeof clocks / sizeof clocks[0]; c++) {
        for (size_t r = 0; r < sizeof rates / sizeof rates[0]; r++) {
            brute_t ref = brute_force(clocks[c], rates[r]);
            stm32_can_timing_t t;
            bool ok = stm32_can_timing((uint32_t)clocks[c], (uint32_t)rates[r], &t);
            TEST_ASSERT_EQUAL_INT(ref.found, ok);
            if (!ok) {
                continue;
            }
            cases++;
            unsigned tq = 1u + t.bs1 + t.bs2;
            TEST_ASSERT_TRUE(t.bs1 >= 1u && t.bs1 <= 16u && t.bs2 >= 1u && t.bs2 <= 8u);
            TEST_ASSERT_EQUAL_UINT64(clocks[c], (unsigned long long)t.brp * tq * rates[r]);
            double err = (double)(1u + t.bs1) / tq - 0.875;
            err = err < 0 ? -err : err;
            TEST_ASSERT_DOUBLE_WITHIN(1e-12, ref.best_err, err);
            TEST_ASSERT_EQUAL_UINT(ref.best_brp, t.brp);
            TEST_ASSERT_EQUAL_UINT(1u, t.sjw);
        }
    }
    TEST_ASSERT_GREATER_OR_EQUAL(25, cases); /* most combinations have a setting */
    stm32_can_timing_t t;
    TEST_ASSERT_FALSE(stm32_can_timing(42000000u, 1300000u, &t)); /* 42 / 1.3 not whole */
    TEST_ASSERT_FALSE(brute_force(42000000ul, 1300000ul).found);
}

/* Published bxCAN values for a 42 MHz APB1 clock, sample point 87.5 %
 * (bittiming.can-wiki.info, "ST Microelectronics bxCAN" at 42 MHz):
 * 1000 kbit/s -> BTR 0x001a0002, 500 kbit/s -> 0x001a0005. */
static void test_bit_timing_matches_published_register_values(void)
{
    stm32_can_timing_t t;
    TEST_ASSERT_TRUE(stm32_can_timing(42000000u, 1000000u, &t));
    TEST_ASSERT_EQUAL_HEX32(0x001A0002u, stm32_can_btr(&t));
    TEST_ASSERT_TRUE(stm32_can_timing(42000000u, 500000u, &t));
    TEST_ASSERT_EQUAL_HEX32(0x001A0005u, stm32_can_btr(&t));
}

static void test_init_handshake_and_configuration(void)
{
    start();
    TEST_ASSERT_EQUAL_UINT(0u, g_model.violations);
    TEST_ASSERT_EQUAL_UINT(0u, reg_model_stray_accesses());
    TEST_ASSERT_EQUAL_HEX32(0x001A0002u, g_model.regs.BTR); /* written in init mode */
    TEST_ASSERT_TRUE(g_model.regs.MCR & STM32_CAN_MCR_ABOM);
    TEST_ASSERT_TRUE(g_model.regs.MCR & STM32_CAN_MCR_TXFP);
    TEST_ASSERT_FALSE(g_model.regs.MCR & (STM32_CAN_MCR_SLEEP | STM32_CAN_MCR_INRQ));
    TEST_ASSERT_FALSE(g_model.regs.MSR & (STM32_CAN_MSR_INAK | STM32_CAN_MSR_SLAK));
    TEST_ASSERT_EQUAL_HEX32(0u, g_model.regs.FA1R); /* nothing accepted until asked */

    setUp();
    stm32_can_config_t c = config(42000000u, 500000u);
    c.loopback = true;
    TEST_ASSERT_EQUAL_INT(HAL_OK, stm32_can_init(&g_drv, &c));
    TEST_ASSERT_EQUAL_HEX32(0x001A0005u | STM32_CAN_BTR_LBKM | STM32_CAN_BTR_SILM,
                            g_model.regs.BTR);
}

static void test_init_fails_within_the_bound_without_acknowledge(void)
{
    g_model.no_clock = true; /* MSR never changes */
    stm32_can_config_t c = config(42000000u, 1000000u);
    TEST_ASSERT_EQUAL_INT(HAL_ERR_IO, stm32_can_init(&g_drv, &c));
    TEST_ASSERT_LESS_OR_EQUAL(POLLS + 8u, g_model.rm.reads);
    hal_can_frame_t f = frame(0x181u, 0u);
    TEST_ASSERT_EQUAL_INT(HAL_ERR_FAULT, stm32_can_send(&g_drv, &f));

    setUp();
    g_model.bus_dominant = true; /* init entered, normal mode never reached */
    TEST_ASSERT_EQUAL_INT(HAL_ERR_IO, stm32_can_init(&g_drv, &c));
    TEST_ASSERT_EQUAL_INT(CAN_MODE_INIT, g_model.mode);
    TEST_ASSERT_LESS_OR_EQUAL(2u * POLLS + 16u, g_model.rm.reads);
    TEST_ASSERT_EQUAL_INT(HAL_ERR_FAULT, stm32_can_send(&g_drv, &f));

    setUp();
    c.bitrate = 1300000u; /* no exact timing: refused before touching the bus */
    TEST_ASSERT_EQUAL_INT(HAL_ERR_RANGE, stm32_can_init(&g_drv, &c));
}

static bool deliver(uint32_t id, uint8_t flags)
{
    hal_can_frame_t f = frame(id, 0x10u);
    f.flags = flags;
    return can_model_deliver(&g_model, &f);
}

static void test_filter_accepts_exactly_the_command_ids(void)
{
    start();
    TEST_ASSERT_FALSE(deliver(0x601u, 0u)); /* no filter yet: nothing */
    /* The firmware's ids: 29-bit command and feed-forward ids of its node. */
    const uint32_t cmd = 0x01D00301u, ff = 0x01D00501u;
    const uint32_t ids[] = {cmd | HAL_CAN_ID_EXT_BIT, ff | HAL_CAN_ID_EXT_BIT};
    TEST_ASSERT_EQUAL_INT(HAL_OK, stm32_can_set_filter(&g_drv, ids, 2u));
    TEST_ASSERT_TRUE(deliver(cmd, HAL_CAN_FLAG_EXT));
    TEST_ASSERT_TRUE(deliver(ff, HAL_CAN_FLAG_EXT));
    TEST_ASSERT_FALSE(deliver(cmd + 1u, HAL_CAN_FLAG_EXT));  /* another node */
    TEST_ASSERT_FALSE(deliver(cmd - 0x100u, HAL_CAN_FLAG_EXT));
    TEST_ASSERT_FALSE(deliver(cmd & 0x7FFu, 0u));              /* 11-bit look-alike */
    TEST_ASSERT_FALSE(deliver(cmd, HAL_CAN_FLAG_EXT | HAL_CAN_FLAG_RTR));
    TEST_ASSERT_EQUAL_UINT(0u, g_model.violations);
    hal_can_frame_t got;
    TEST_ASSERT_EQUAL_INT(HAL_OK, stm32_can_recv(&g_drv, &got));
    TEST_ASSERT_EQUAL_HEX32(cmd, got.id);
    TEST_ASSERT_EQUAL_UINT8(HAL_CAN_FLAG_EXT, got.flags);
    TEST_ASSERT_EQUAL_INT(HAL_OK, stm32_can_recv(&g_drv, &got));
    TEST_ASSERT_EQUAL_HEX32(ff, got.id);

    /* A node-id change: the new ids replace the old ones. */
    const uint32_t moved = (cmd + 4u) | HAL_CAN_ID_EXT_BIT;
    TEST_ASSERT_EQUAL_INT(HAL_OK, stm32_can_set_filter(&g_drv, &moved, 1u));
    TEST_ASSERT_FALSE(deliver(cmd, HAL_CAN_FLAG_EXT));
    TEST_ASSERT_FALSE(deliver(ff, HAL_CAN_FLAG_EXT));
    TEST_ASSERT_TRUE(deliver(cmd + 4u, HAL_CAN_FLAG_EXT));

    /* Standard ids and a full set of eight (four banks). */
    const uint32_t eight[] = {0x601u, 0x602u, 0x603u, cmd | HAL_CAN_ID_EXT_BIT,
                              0x7E5u, 0x000u, 0x1FFFFFFFu | HAL_CAN_ID_EXT_BIT, 0x100u};
    TEST_ASSERT_EQUAL_INT(HAL_OK, stm32_can_set_filter(&g_drv, eight, 8u));
    while (stm32_can_recv(&g_drv, &got) == HAL_OK) {
    }
    for (size_t i = 0; i < 8u; i++) {
        bool ext = (eight[i] & HAL_CAN_ID_EXT_BIT) != 0u;
        uint32_t id = eight[i] & ~HAL_CAN_ID_EXT_BIT;
        TEST_ASSERT_TRUE(deliver(id, ext ? HAL_CAN_FLAG_EXT : 0u));
        TEST_ASSERT_EQUAL_INT(HAL_OK, stm32_can_recv(&g_drv, &got));
        TEST_ASSERT_EQUAL_HEX32(id, got.id);
    }
    TEST_ASSERT_FALSE(deliver(0x604u, 0u));
    TEST_ASSERT_FALSE(deliver(0x601u, HAL_CAN_FLAG_EXT));

    /* No ids: everything is accepted. */
    TEST_ASSERT_EQUAL_INT(HAL_OK, stm32_can_set_filter(&g_drv, NULL, 0u));
    TEST_ASSERT_TRUE(deliver(0x123u, 0u));
    TEST_ASSERT_TRUE(deliver(0x1234567u, HAL_CAN_FLAG_EXT));

    const uint32_t nine[9] = {1, 2, 3, 4, 5, 6, 7, 8, 9};
    TEST_ASSERT_EQUAL_INT(HAL_ERR_RANGE, stm32_can_set_filter(&g_drv, nine, 9u));
    const uint32_t too_big = 0x800u;
    TEST_ASSERT_EQUAL_INT(HAL_ERR_RANGE, stm32_can_set_filter(&g_drv, &too_big, 1u));
    const uint32_t ext_too_big = 0x20000000u | HAL_CAN_ID_EXT_BIT;
    TEST_ASSERT_EQUAL_INT(HAL_ERR_RANGE, stm32_can_set_filter(&g_drv, &ext_too_big, 1u));
    TEST_ASSERT_EQUAL_UINT(0u, g_model.violations);
}

static void test_receive_fifo_order_release_and_overrun(void)
{
    start();
    const uint32_t ids[] = {0x601u, 0x602u};
    TEST_ASSERT_EQUAL_INT(HAL_OK, stm32_can_set_filter(&g_drv, ids, 2u));
    TEST_ASSERT_EQUAL_UINT(0u, g_model.violations);
    hal_can_frame_t a = frame(0x601u, 1u), b = frame(0x602u, 2u), c = frame(0x601u, 3u);
    c.len = 3u;
    TEST_ASSERT_TRUE(can_model_deliver(&g_model, &a));
    TEST_ASSERT_TRUE(can_model_deliver(&g_model, &b));
    TEST_ASSERT_TRUE(can_model_deliver(&g_model, &c));
    TEST_ASSERT_EQUAL_UINT(3u, stm32_reg_read(&g_model.regs.RF0R) & STM32_CAN_RFR_FMP_MASK);
    hal_can_frame_t d = frame(0x602u, 9u); /* FIFO full: overwrites the last */
    TEST_ASSERT_TRUE(can_model_deliver(&g_model, &d));

    hal_can_frame_t got;
    TEST_ASSERT_EQUAL_INT(HAL_OK, stm32_can_recv(&g_drv, &got));
    TEST_ASSERT_EQUAL_HEX32(0x601u, got.id);
    TEST_ASSERT_EQUAL_UINT8(8u, got.len);
    TEST_ASSERT_EQUAL_MEMORY(a.data, got.data, 8u);
    TEST_ASSERT_EQUAL_UINT8(0u, got.flags);
    TEST_ASSERT_EQUAL_UINT(1u, g_drv.counters.can_rx_overruns);
    TEST_ASSERT_EQUAL_UINT(2u, g_model.fifo_count); /* RFOM released one */
    TEST_ASSERT_EQUAL_INT(HAL_OK, stm32_can_recv(&g_drv, &got));
    TEST_ASSERT_EQUAL_HEX32(0x602u, got.id);
    TEST_ASSERT_EQUAL_MEMORY(b.data, got.data, 8u);
    TEST_ASSERT_EQUAL_INT(HAL_OK, stm32_can_recv(&g_drv, &got));
    TEST_ASSERT_EQUAL_MEMORY(d.data, got.data, 8u);
    TEST_ASSERT_EQUAL_INT(HAL_ERR_NO_DATA, stm32_can_recv(&g_drv, &got));
    hal_counters_t cnt;
    stm32_can_counters(&g_drv, &cnt);
    TEST_ASSERT_EQUAL_UINT(3u, cnt.can_rx);
    TEST_ASSERT_EQUAL_UINT(0u, g_model.regs.RF0R & (STM32_CAN_RFR_FOVR | STM32_CAN_RFR_FULL));
}

/* Steps the bus and services the driver until nothing is pending. */
static void drain(int max_steps)
{
    for (int i = 0; i < max_steps; i++) {
        (void)can_model_bus_step(&g_model);
        stm32_can_tx_service(&g_drv);
    }
}

static void test_mailboxes_then_queue_keep_the_order(void)
{
    start();
    /* Decreasing priority order and mixed ids: the wire must show the send
     * order (TXFP), not the arbitration order. */
    const uint32_t ids[] = {0x700u, 0x100u, 0x300u, 0x181u, 0x101u, 0x580u, 0x102u, 0x050u};
    for (size_t i = 0; i < 8u; i++) {
        hal_can_frame_t f = frame(ids[i], (uint8_t)(16u * i));
        f.len = (uint8_t)(i + 1u);
        TEST_ASSERT_EQUAL_INT(HAL_OK, stm32_can_send(&g_drv, &f));
    }
    TEST_ASSERT_EQUAL_UINT(0u, g_model.regs.TSR & (7u << 26)); /* three mailboxes busy */
    TEST_ASSERT_EQUAL_UINT(5u, g_drv.txq_count);
    drain(20);
    TEST_ASSERT_EQUAL_UINT(8u, g_model.wire_count);
    for (size_t i = 0; i < 8u; i++) {
        TEST_ASSERT_EQUAL_HEX32(ids[i], g_model.wire[i].id);
        TEST_ASSERT_EQUAL_UINT8(i + 1u, g_model.wire[i].len);
        /* every byte the frame has, and zeros in the mailbox beyond it */
        for (size_t j = 0; j < 8u; j++) {
            TEST_ASSERT_EQUAL_UINT8(j <= i ? 16u * i + j : 0u, g_model.wire[i].data[j]);
        }
    }
    hal_counters_t cnt;
    stm32_can_counters(&g_drv, &cnt);
    TEST_ASSERT_EQUAL_UINT(8u, cnt.can_tx_ok);
    TEST_ASSERT_EQUAL_UINT(0u, g_drv.txq_count);

    /* A mailbox frees up before the interrupt has refilled it: a new frame
     * must still go behind the queued ones. */
    for (uint32_t i = 0; i < 5u; i++) {
        hal_can_frame_t f = frame(0x200u + i, 0u);
        TEST_ASSERT_EQUAL_INT(HAL_OK, stm32_can_send(&g_drv, &f));
    }
    TEST_ASSERT_TRUE(can_model_bus_step(&g_model)); /* 0x200 out, no service yet */
    hal_can_frame_t late = frame(0x205u, 0u);
    TEST_ASSERT_EQUAL_INT(HAL_OK, stm32_can_send(&g_drv, &late));
    drain(10);
    TEST_ASSERT_EQUAL_UINT(14u, g_model.wire_count);
    for (uint32_t i = 0; i < 6u; i++) {
        TEST_ASSERT_EQUAL_HEX32(0x200u + i, g_model.wire[8u + i].id);
    }
    TEST_ASSERT_EQUAL_UINT(0u, g_model.violations);
    TEST_ASSERT_EQUAL_UINT(0u, g_model.regs.TSR & 0x030303u); /* RQCP/TXOK cleared */
}

static void test_full_queue_is_busy_and_counted(void)
{
    start();
    hal_can_frame_t f = frame(0x181u, 0u);
    for (uint32_t i = 0; i < 3u + STM32_CAN_TXQ; i++) {
        TEST_ASSERT_EQUAL_INT(HAL_OK, stm32_can_send(&g_drv, &f));
    }
    TEST_ASSERT_EQUAL_INT(HAL_ERR_BUSY, stm32_can_send(&g_drv, &f));
    TEST_ASSERT_EQUAL_INT(HAL_ERR_BUSY, stm32_can_send(&g_drv, &f));
    hal_counters_t cnt;
    stm32_can_counters(&g_drv, &cnt);
    TEST_ASSERT_EQUAL_UINT(2u, cnt.can_tx_dropped);
    drain(3 + (int)STM32_CAN_TXQ + 2);
    TEST_ASSERT_EQUAL_UINT(3u + STM32_CAN_TXQ, g_model.wire_count);
    TEST_ASSERT_EQUAL_INT(HAL_OK, stm32_can_send(&g_drv, &f));
}

static void test_frame_formats(void)
{
    start();
    hal_can_frame_t f = frame(0x181u, 0u);
    f.len = 9u;
    TEST_ASSERT_EQUAL_INT(HAL_ERR_RANGE, stm32_can_send(&g_drv, &f));
    f = frame(0x181u, 0u);
    f.flags = HAL_CAN_FLAG_FD;
    TEST_ASSERT_EQUAL_INT(HAL_ERR_RANGE, stm32_can_send(&g_drv, &f));
    f = frame(0x800u, 0u);
    TEST_ASSERT_EQUAL_INT(HAL_ERR_RANGE, stm32_can_send(&g_drv, &f));
    f = frame(0x1ABCDEFu, 5u);
    f.flags = HAL_CAN_FLAG_EXT;
    f.len = 2u;
    TEST_ASSERT_EQUAL_INT(HAL_OK, stm32_can_send(&g_drv, &f));
    hal_can_frame_t r = frame(0x123u, 0u);
    r.flags = HAL_CAN_FLAG_RTR;
    r.len = 0u;
    TEST_ASSERT_EQUAL_INT(HAL_OK, stm32_can_send(&g_drv, &r));
    drain(4);
    TEST_ASSERT_EQUAL_UINT(2u, g_model.wire_count);
    TEST_ASSERT_EQUAL_HEX32(0x1ABCDEFu, g_model.wire[0].id);
    TEST_ASSERT_EQUAL_UINT8(HAL_CAN_FLAG_EXT, g_model.wire[0].flags);
    TEST_ASSERT_EQUAL_UINT8(2u, g_model.wire[0].len);
    TEST_ASSERT_EQUAL_UINT8(5u, g_model.wire[0].data[0]);
    TEST_ASSERT_EQUAL_UINT8(6u, g_model.wire[0].data[1]);
    TEST_ASSERT_EQUAL_UINT8(0u, g_model.wire[0].data[2]); /* beyond len: not sent */
    TEST_ASSERT_EQUAL_UINT8(HAL_CAN_FLAG_RTR, g_model.wire[1].flags);

    /* Extended frames decode on receive too. */
    TEST_ASSERT_EQUAL_INT(HAL_OK, stm32_can_set_filter(&g_drv, NULL, 0u));
    TEST_ASSERT_TRUE(can_model_deliver(&g_model, &f));
    hal_can_frame_t got;
    TEST_ASSERT_EQUAL_INT(HAL_OK, stm32_can_recv(&g_drv, &got));
    TEST_ASSERT_EQUAL_HEX32(0x1ABCDEFu, got.id);
    TEST_ASSERT_EQUAL_UINT8(HAL_CAN_FLAG_EXT, got.flags);
    TEST_ASSERT_EQUAL_UINT8(2u, got.len);
}

static void test_bus_off_recovers_and_is_counted_once(void)
{
    start();
    hal_can_frame_t f = frame(0x181u, 0u);
    TEST_ASSERT_EQUAL_INT(HAL_OK, stm32_can_send(&g_drv, &f));
    g_model.inject_errors = 32u; /* TEC +8 each: bus-off after the 32nd */
    for (int i = 0; i < 32; i++) {
        (void)can_model_bus_step(&g_model);
        stm32_can_tx_service(&g_drv);
    }
    TEST_ASSERT_TRUE(g_model.regs.ESR & STM32_CAN_ESR_BOFF);
    hal_counters_t cnt;
    stm32_can_counters(&g_drv, &cnt);
    TEST_ASSERT_EQUAL_UINT(1u, cnt.can_bus_off);
    TEST_ASSERT_GREATER_OR_EQUAL(1u, cnt.can_error_frames);
    TEST_ASSERT_EQUAL_INT(HAL_ERR_FAULT, stm32_can_send(&g_drv, &f));
    TEST_ASSERT_EQUAL_UINT(0u, g_model.wire_count);
    stm32_can_tx_service(&g_drv);
    stm32_can_tx_service(&g_drv);
    stm32_can_counters(&g_drv, &cnt);
    TEST_ASSERT_EQUAL_UINT(1u, cnt.can_bus_off); /* still the same episode */

    for (uint32_t i = 0; i < g_model.recovery_steps; i++) { /* ABOM: rejoins by itself */
        (void)can_model_bus_step(&g_model);
        stm32_can_tx_service(&g_drv);
    }
    TEST_ASSERT_FALSE(g_model.regs.ESR & STM32_CAN_ESR_BOFF);
    TEST_ASSERT_EQUAL_INT(HAL_OK, stm32_can_send(&g_drv, &f));
    drain(4);
    TEST_ASSERT_EQUAL_UINT(2u, g_model.wire_count); /* the pending one, then the new one */
    stm32_can_counters(&g_drv, &cnt);
    TEST_ASSERT_EQUAL_UINT(1u, cnt.can_bus_off);
    TEST_ASSERT_EQUAL_UINT(2u, cnt.can_tx_ok);

    g_model.inject_errors = 40u; /* a second episode is a second count */
    TEST_ASSERT_EQUAL_INT(HAL_OK, stm32_can_send(&g_drv, &f));
    drain(40);
    stm32_can_counters(&g_drv, &cnt);
    TEST_ASSERT_EQUAL_UINT(2u, cnt.can_bus_off);
}

static void test_each_new_bus_error_counts_once(void)
{
    start();
    hal_can_frame_t f = frame(0x181u, 0u);
    TEST_ASSERT_EQUAL_INT(HAL_OK, stm32_can_send(&g_drv, &f));
    g_model.inject_errors = 1u;
    (void)can_model_bus_step(&g_model);
    stm32_can_tx_service(&g_drv);
    stm32_can_tx_service(&g_drv);
    hal_counters_t cnt;
    stm32_can_counters(&g_drv, &cnt);
    TEST_ASSERT_EQUAL_UINT(1u, cnt.can_error_frames);
    TEST_ASSERT_EQUAL_UINT(STM32_CAN_ESR_LEC_USER,
                           (g_model.regs.ESR & STM32_CAN_ESR_LEC_MASK) >> STM32_CAN_ESR_LEC_POS);
    TEST_ASSERT_EQUAL_UINT(8u, cnt.can_tx_error_count); /* RM0090: +8 per transmit error */
    TEST_ASSERT_EQUAL_UINT(0u, cnt.can_rx_error_count);
    drain(2);
    stm32_can_counters(&g_drv, &cnt);
    TEST_ASSERT_EQUAL_UINT(1u, cnt.can_error_frames);
    TEST_ASSERT_EQUAL_UINT(1u, g_model.wire_count);
}

/* A mailbox that completes without TXOK (RM0090: RQCP set, TXOK clear,
 * TERR or ALST set: aborted, or not retransmitted) is a frame the bus never
 * carried: counted as aborted, not as sent, and its flags cleared. */
static void test_mailbox_completed_without_txok_counts_as_aborted(void)
{
    start();
    const uint32_t shift = STM32_CAN_TSR_MAILBOX_SHIFT * 1u;
    const uint32_t terr = STM32_CAN_TSR_RQCP0 << 3u; /* TERR0, bit 3 */
    g_model.regs.TSR |= (STM32_CAN_TSR_RQCP0 | terr) << shift;
    stm32_can_tx_service(&g_drv);
    hal_counters_t cnt;
    stm32_can_counters(&g_drv, &cnt);
    TEST_ASSERT_EQUAL_UINT(1u, cnt.can_tx_aborted);
    TEST_ASSERT_EQUAL_UINT(0u, cnt.can_tx_ok);
    TEST_ASSERT_EQUAL_UINT(0u, g_model.regs.TSR & (STM32_CAN_TSR_RQCP0 << shift));
    stm32_can_tx_service(&g_drv); /* counted once */
    stm32_can_counters(&g_drv, &cnt);
    TEST_ASSERT_EQUAL_UINT(1u, cnt.can_tx_aborted);
}

int main(int argc, char **argv)
{
    if (UnityParseOptions(argc, argv) != 0) {
        return 1;
    }
    UNITY_BEGIN();
    RUN_TEST(test_register_offsets_match_rm0090);
    RUN_TEST(test_bit_timing_is_the_best_exact_setting);
    RUN_TEST(test_bit_timing_matches_published_register_values);
    RUN_TEST(test_init_handshake_and_configuration);
    RUN_TEST(test_init_fails_within_the_bound_without_acknowledge);
    RUN_TEST(test_filter_accepts_exactly_the_command_ids);
    RUN_TEST(test_receive_fifo_order_release_and_overrun);
    RUN_TEST(test_mailboxes_then_queue_keep_the_order);
    RUN_TEST(test_full_queue_is_busy_and_counted);
    RUN_TEST(test_frame_formats);
    RUN_TEST(test_bus_off_recovers_and_is_counted_once);
    RUN_TEST(test_each_new_bus_error_counts_once);
    RUN_TEST(test_mailbox_completed_without_txok_counts_as_aborted);
    return UNITY_END();
}
