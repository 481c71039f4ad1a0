/*
 * SocketCAN backend logic without a CAN kernel: frame conversion against the
 * Linux ABI (bit values from linux/can.h, written out as literals so a wrong
 * header use shows), the bounded transmit queue and the error/bus-off state
 * machine driven by a fake socket, and open() failing cleanly.  The same
 * backend runs against a real kernel socket in the VM test (hd_vm_can_test).
 */
#include <string.h>

#include <linux/can.h>
#include <linux/can/error.h>

#include "hal_socketcan.h"
#include "hal_socketcan_core.h"
#include "unity.h"

/* ---- fake socket ---------------------------------------------------- */
#define FAKE_MAX 256
typedef struct {
    int accept_left;       /* writes accepted before EAGAIN; <0: unlimited */
    int write_error;       /* when set, write returns HAL_ERR_IO */
    uint32_t written_ids[FAKE_MAX];
    int n_written;
    hal_can_frame_t rx[FAKE_MAX];
    int n_rx, rx_pos, reads;
} fake_t;

static fake_t fk;
static hsc_core_t core;

static int fake_write(void *io, const hal_can_frame_t *f)
{
    fake_t *k = io;
    if (k->write_error) {
        return HAL_ERR_IO;
    }
    if (k->accept_left == 0) {
        return HSC_IO_AGAIN;
    }
    if (k->accept_left > 0) {
        k->accept_left--;
    }
    k->written_ids[k->n_written++] = f->id;
    return 0;
}

static int fake_read(void *io, hal_can_frame_t *f)
{
    fake_t *k = io;
    k->reads++;
    if (k->rx_pos >= k->n_rx) {
        return HSC_IO_AGAIN;
    }
    *f = k->rx[k->rx_pos++];
    return 0;
}

static void fake_rx_error(uint32_t err_class)
{
    hal_can_frame_t e = {.id = err_class, .len = 8, .flags = HAL_CAN_FLAG_ERR};
    fk.rx[fk.n_rx++] = e;
}

static void fake_rx_data(uint32_t id)
{
    hal_can_frame_t d = {.id = id, .len = 1, .data = {0x5A}};
    fk.rx[fk.n_rx++] = d;
}

static hal_can_frame_t frame(uint32_t id, uint8_t len)
{
    hal_can_frame_t f = {.id = id, .len = len};
    for (uint8_t i = 0; i < len; ++i) {
        f.data[i] = (uint8_t)(i * 7u + 1u);
    }
    return f;
}

void setUp(void)
{
    memset(&fk, 0, sizeof(fk));
    fk.accept_left = -1;
    hsc_core_init(&core, false);
}

void tearDown(void) {}

/* ---- conversion ----------------------------------------------------- */
static void test_classic_std_frame_to_linux(void)
{
    hal_can_frame_t f = frame(0x123, 8);
    struct canfd_frame lf;
    size_t n = 0;
    TEST_ASSERT_EQUAL_INT(HAL_OK, hsc_to_linux(&f, &lf, &n));
    TEST_ASSERT_EQUAL_size_t(16u, n); /* CAN_MTU: 4 id + 4 header + 8 data */
    TEST_ASSERT_EQUAL_HEX32(0x123u, lf.can_id);
    TEST_ASSERT_EQUAL_UINT8(8u, lf.len);
    TEST_ASSERT_EQUAL_MEMORY(f.data, lf.data, 8);
}

static void test_ext_rtr_flags_to_linux(void)
{
    hal_can_frame_t f = frame(0x1ABCDEF0, 0);
    f.flags = HAL_CAN_FLAG_EXT | HAL_CAN_FLAG_RTR;
    struct canfd_frame lf;
    size_t n;
    TEST_ASSERT_EQUAL_INT(HAL_OK, hsc_to_linux(&f, &lf, &n));
    /* Kernel ABI: bit 31 = extended, bit 30 = remote request. */
    TEST_ASSERT_EQUAL_HEX32(0x80000000u | 0x40000000u | 0x1ABCDEF0u, lf.can_id);
}

static void test_fd_frame_roundtrip(void)
{
    hal_can_frame_t f = frame(0x7FF, 64);
    f.flags = HAL_CAN_FLAG_FD;
    struct canfd_frame lf;
    size_t n;
    TEST_ASSERT_EQUAL_INT(HAL_OK, hsc_to_linux(&f, &lf, &n));
    TEST_ASSERT_EQUAL_size_t(72u, n); /* CANFD_MTU */
    hal_can_frame_t back;
    TEST_ASSERT_EQUAL_INT(HAL_OK, hsc_from_linux(&lf, n, &back));
    TEST_ASSERT_EQUAL_HEX32(f.id, back.id);
    TEST_ASSERT_EQUAL_UINT8(64u, back.len);
    TEST_ASSERT_EQUAL_UINT8(HAL_CAN_FLAG_FD, back.flags);
    TEST_ASSERT_EQUAL_MEMORY(f.data, back.data, 64);
}

static void test_from_linux_ext_and_error_frames(void)
{
    struct canfd_frame lf;
    memset(&lf, 0, sizeof(lf));
    hal_can_frame_t out;
    lf.can_id = 0x80000000u | 0x00012345u;
    lf.len = 2;
    TEST_ASSERT_EQUAL_INT(HAL_OK, hsc_from_linux(&lf, 16, &out));
    TEST_ASSERT_EQUAL_HEX32(0x12345u, out.id);
    TEST_ASSERT_EQUAL_UINT8(HAL_CAN_FLAG_EXT, out.flags);
    /* Error frame: bit 29, class bits below; 0x40 is bus-off. */
    lf.can_id = 0x20000000u | 0x40u;
    lf.len = 8;
    TEST_ASSERT_EQUAL_INT(HAL_OK, hsc_from_linux(&lf, 16, &out));
    TEST_ASSERT_TRUE((out.flags & HAL_CAN_FLAG_ERR) != 0u);
    TEST_ASSERT_EQUAL_HEX32(0x40u, out.id);
}

static void test_from_linux_rejects_odd_reads(void)
{
    struct canfd_frame lf;
    memset(&lf, 0, sizeof(lf));
    hal_can_frame_t out;
    TEST_ASSERT_EQUAL_INT(HAL_ERR_RANGE, hsc_from_linux(&lf, 10, &out));
    lf.len = 9; /* more than a classic frame holds */
    TEST_ASSERT_EQUAL_INT(HAL_ERR_RANGE, hsc_from_linux(&lf, 16, &out));
    lf.len = 65;
    TEST_ASSERT_EQUAL_INT(HAL_ERR_RANGE, hsc_from_linux(&lf, 72, &out));
}

static void test_invalid_frames_rejected(void)
{
    hal_can_frame_t f = frame(0x800, 1); /* 12 bits in a standard id */
    TEST_ASSERT_FALSE(hsc_frame_valid(&f, true));
    f = frame(0x20000000, 1);
    f.flags = HAL_CAN_FLAG_EXT; /* 30 bits */
    TEST_ASSERT_FALSE(hsc_frame_valid(&f, true));
    f = frame(0x10, 9); /* classic frames hold 8 bytes */
    TEST_ASSERT_FALSE(hsc_frame_valid(&f, true));
    f = frame(0x10, 13);
    f.flags = HAL_CAN_FLAG_FD; /* 13 is not an FD length */
    TEST_ASSERT_FALSE(hsc_frame_valid(&f, true));
    f.len = 12;
    TEST_ASSERT_TRUE(hsc_frame_valid(&f, true));
    TEST_ASSERT_FALSE(hsc_frame_valid(&f, false)); /* classic-only socket */
    f.flags |= HAL_CAN_FLAG_RTR; /* FD has no remote frames */
    TEST_ASSERT_FALSE(hsc_frame_valid(&f, true));
    TEST_ASSERT_FALSE(hsc_frame_valid(NULL, true));
    TEST_ASSERT_EQUAL_UINT8(20u, hsc_fd_len_round_up(17));
    TEST_ASSERT_EQUAL_UINT8(64u, hsc_fd_len_round_up(49));
}

static void test_filters_for_node_ids(void)
{
    const uint32_t ids[] = {0x601, 0x1FFFFFFFu | HAL_SOCKETCAN_ID_EXT};
    struct can_filter fl[HAL_SOCKETCAN_MAX_RX_IDS];
    TEST_ASSERT_EQUAL_size_t(2u, hsc_build_filters(ids, 2, fl));
    TEST_ASSERT_EQUAL_HEX32(0x601u, fl[0].can_id);
    TEST_ASSERT_EQUAL_HEX32(0x800007FFu, fl[0].can_mask);
    TEST_ASSERT_EQUAL_HEX32(0x9FFFFFFFu, fl[1].can_id);
    TEST_ASSERT_EQUAL_HEX32(0x9FFFFFFFu, fl[1].can_mask);
    const uint32_t bad[] = {0x800};
    TEST_ASSERT_EQUAL_size_t(0u, hsc_build_filters(bad, 1, fl));
    uint32_t many[HAL_SOCKETCAN_MAX_RX_IDS + 1] = {0};
    TEST_ASSERT_EQUAL_size_t(0u, hsc_build_filters(many, HAL_SOCKETCAN_MAX_RX_IDS + 1, fl));
}

/* ---- transmit queue ------------------------------------------------- */
static void test_queue_fills_then_busy_and_drains_in_order(void)
{
    const int direct = 5;
    const int total = direct + (int)HAL_SOCKETCAN_TXQ_LEN + 3;
    fk.accept_left = direct;
    int busy = 0;
    for (int i = 0; i < total; ++i) {
        hal_can_frame_t f = frame((uint32_t)i, 8);
        int r = hsc_core_send(&core, &f, fake_write, &fk);
        if (r == HAL_ERR_BUSY) {
            busy++;
        } else {
            TEST_ASSERT_EQUAL_INT(HAL_OK, r);
        }
    }
    TEST_ASSERT_EQUAL_INT(3, busy);
    TEST_ASSERT_EQUAL_size_t(HAL_SOCKETCAN_TXQ_LEN, core.txq_count);
    TEST_ASSERT_EQUAL_UINT32(direct, core.counters.can_tx_ok);
    TEST_ASSERT_EQUAL_UINT32(3u, core.counters.can_tx_dropped);
    /* The socket drains: a recv call (nothing to read) empties the queue,
     * in the order the frames were sent. */
    fk.accept_left = -1;
    hal_can_frame_t in;
    TEST_ASSERT_EQUAL_INT(HAL_ERR_NO_DATA, hsc_core_recv(&core, &in, fake_read, fake_write, &fk));
    TEST_ASSERT_EQUAL_size_t(0u, core.txq_count);
    TEST_ASSERT_EQUAL_INT(direct + (int)HAL_SOCKETCAN_TXQ_LEN, fk.n_written);
    for (int i = 0; i < fk.n_written; ++i) {
        TEST_ASSERT_EQUAL_UINT32((uint32_t)i, fk.written_ids[i]);
    }
    TEST_ASSERT_EQUAL_UINT32(direct + HAL_SOCKETCAN_TXQ_LEN, core.counters.can_tx_ok);
}

static void test_queued_frames_go_before_new_ones(void)
{
    fk.accept_left = 0;
    hal_can_frame_t a = frame(1, 1), b = frame(2, 1), c = frame(3, 1);
    TEST_ASSERT_EQUAL_INT(HAL_OK, hsc_core_send(&core, &a, fake_write, &fk));
    TEST_ASSERT_EQUAL_INT(HAL_OK, hsc_core_send(&core, &b, fake_write, &fk));
    fk.accept_left = 1; /* room for one: it must be the oldest */
    TEST_ASSERT_EQUAL_INT(HAL_OK, hsc_core_send(&core, &c, fake_write, &fk));
    TEST_ASSERT_EQUAL_INT(1, fk.n_written);
    TEST_ASSERT_EQUAL_UINT32(1u, fk.written_ids[0]);
    TEST_ASSERT_EQUAL_size_t(2u, core.txq_count);
}

static void test_write_error_is_io_and_counted(void)
{
    fk.write_error = 1;
    hal_can_frame_t f = frame(0x10, 2);
    TEST_ASSERT_EQUAL_INT(HAL_ERR_IO, hsc_core_send(&core, &f, fake_write, &fk));
    TEST_ASSERT_EQUAL_UINT32(1u, core.counters.can_tx_dropped);
    TEST_ASSERT_EQUAL_UINT32(0u, core.counters.can_tx_ok);
}

static void test_bad_frame_is_range_not_queued(void)
{
    hal_can_frame_t f = frame(0x10, 9);
    TEST_ASSERT_EQUAL_INT(HAL_ERR_RANGE, hsc_core_send(&core, &f, fake_write, &fk));
    f = frame(0x10, 12);
    f.flags = HAL_CAN_FLAG_FD; /* core opened without FD */
    TEST_ASSERT_EQUAL_INT(HAL_ERR_RANGE, hsc_core_send(&core, &f, fake_write, &fk));
    TEST_ASSERT_EQUAL_INT(0, fk.n_written);
    TEST_ASSERT_EQUAL_size_t(0u, core.txq_count);
}

/* ---- receive, error frames, bus-off ---------------------------------- */
static void test_error_frames_counted_not_returned(void)
{
    fake_rx_error(CAN_ERR_CRTL);
    fake_rx_error(CAN_ERR_PROT);
    fake_rx_data(0x601);
    hal_can_frame_t in;
    TEST_ASSERT_EQUAL_INT(HAL_OK, hsc_core_recv(&core, &in, fake_read, fake_write, &fk));
    TEST_ASSERT_EQUAL_HEX32(0x601u, in.id);
    TEST_ASSERT_EQUAL_UINT32(2u, core.counters.can_error_frames);
    TEST_ASSERT_EQUAL_UINT32(1u, core.counters.can_rx);
    TEST_ASSERT_EQUAL_UINT32(0u, core.counters.can_bus_off);
    TEST_ASSERT_EQUAL_INT(HAL_ERR_NO_DATA, hsc_core_recv(&core, &in, fake_read, fake_write, &fk));
}

static void test_bus_off_faults_send_until_traffic_returns(void)
{
    hal_can_frame_t f = frame(0x181, 8), in;
    fake_rx_error(CAN_ERR_BUSOFF);
    fake_rx_error(CAN_ERR_BUSOFF); /* repeated report: still one event */
    TEST_ASSERT_EQUAL_INT(HAL_ERR_NO_DATA, hsc_core_recv(&core, &in, fake_read, fake_write, &fk));
    TEST_ASSERT_TRUE(core.bus_off);
    TEST_ASSERT_EQUAL_UINT32(1u, core.counters.can_bus_off);
    TEST_ASSERT_EQUAL_INT(HAL_ERR_FAULT, hsc_core_send(&core, &f, fake_write, &fk));
    TEST_ASSERT_EQUAL_INT(0, fk.n_written);
    /* Another node's frame arrives: the controller is back on the bus. */
    fake_rx_data(0x601);
    TEST_ASSERT_EQUAL_INT(HAL_OK, hsc_core_recv(&core, &in, fake_read, fake_write, &fk));
    TEST_ASSERT_FALSE(core.bus_off);
    TEST_ASSERT_EQUAL_INT(HAL_OK, hsc_core_send(&core, &f, fake_write, &fk));
    TEST_ASSERT_EQUAL_INT(1, fk.n_written);
    /* Second bus-off, recovered by the driver's restart notice. */
    fake_rx_error(CAN_ERR_BUSOFF);
    TEST_ASSERT_EQUAL_INT(HAL_ERR_NO_DATA, hsc_core_recv(&core, &in, fake_read, fake_write, &fk));
    TEST_ASSERT_EQUAL_UINT32(2u, core.counters.can_bus_off);
    fake_rx_error(CAN_ERR_RESTARTED);
    TEST_ASSERT_EQUAL_INT(HAL_ERR_NO_DATA, hsc_core_recv(&core, &in, fake_read, fake_write, &fk));
    TEST_ASSERT_FALSE(core.bus_off);
    TEST_ASSERT_EQUAL_UINT32(4u, core.counters.can_error_frames);
}

/* What the error frame's data says (linux/can/error.h): a controller
 * receive overflow counts as an overrun, TX timeout as an aborted frame,
 * CAN_ERR_CNT carries TEC in data[6] and REC in data[7]. */
static void test_error_frame_data_reaches_the_counters(void)
{
    hal_can_frame_t e = {.id = CAN_ERR_CRTL | CAN_ERR_CNT, .len = 8,
                         .flags = HAL_CAN_FLAG_ERR};
    e.data[1] = CAN_ERR_CRTL_RX_OVERFLOW;
    e.data[6] = 97u;
    e.data[7] = 130u;
    fk.rx[fk.n_rx++] = e;
    fake_rx_error(CAN_ERR_TX_TIMEOUT);
    fake_rx_error(CAN_ERR_CRTL); /* data[1] = 0: no overflow */
    hal_can_frame_t in;
    TEST_ASSERT_EQUAL_INT(HAL_ERR_NO_DATA, hsc_core_recv(&core, &in, fake_read, fake_write, &fk));
    TEST_ASSERT_EQUAL_UINT32(3u, core.counters.can_error_frames);
    TEST_ASSERT_EQUAL_UINT32(1u, core.counters.can_rx_overruns);
    TEST_ASSERT_EQUAL_UINT32(1u, core.counters.can_tx_aborted);
    TEST_ASSERT_EQUAL_UINT32(97u, core.counters.can_tx_error_count);
    TEST_ASSERT_EQUAL_UINT32(130u, core.counters.can_rx_error_count);
}

static void test_recv_bounded_under_error_storm(void)
{
    for (int i = 0; i < 100; ++i) {
        fake_rx_error(CAN_ERR_PROT);
    }
    hal_can_frame_t in;
    TEST_ASSERT_EQUAL_INT(HAL_ERR_NO_DATA, hsc_core_recv(&core, &in, fake_read, fake_write, &fk));
    TEST_ASSERT_EQUAL_INT((int)HSC_RX_BURST, fk.reads);
    TEST_ASSERT_EQUAL_UINT32(HSC_RX_BURST, core.counters.can_error_frames);
}

/* ---- open() on a host without CAN (or without the interface) --------- */
static void test_open_missing_interface_fails_with_message(void)
{
    char err[256] = "";
    const uint32_t ids[] = {0x601};
    hal_socketcan_t *s = hal_socketcan_open("hdnocan9", ids, 1, false, err, sizeof(err));
    TEST_ASSERT_NULL(s);
    TEST_MESSAGE(err);
    /* Either the kernel has no PF_CAN (this CI host) or no such interface. */
    TEST_ASSERT_TRUE(strstr(err, "socket(PF_CAN") != NULL ||
                     strstr(err, "no CAN interface 'hdnocan9'") != NULL);
}

static void test_open_bad_arguments(void)
{
    char err[256] = "";
    TEST_ASSERT_NULL(hal_socketcan_open("a_name_longer_than_ifnamsiz", NULL, 0, false, err, sizeof(err)));
    TEST_ASSERT_NOT_NULL(strstr(err, "bad interface name"));
    TEST_ASSERT_NULL(hal_socketcan_open(NULL, NULL, 0, false, err, sizeof(err)));
    TEST_ASSERT_NOT_NULL(strstr(err, "bad interface name"));
    uint32_t many[HAL_SOCKETCAN_MAX_RX_IDS + 1] = {0};
    TEST_ASSERT_NULL(hal_socketcan_open("vcan0", many, HAL_SOCKETCAN_MAX_RX_IDS + 1, false, err, sizeof(err)));
    TEST_ASSERT_NOT_NULL(strstr(err, "receive ids"));
    hal_socketcan_close(NULL); /* accepted */
}

int main(int argc, char **argv)
{
    if (UnityParseOptions(argc, argv) != 0) {
        return 1;
    }
    UNITY_BEGIN();
    RUN_TEST(test_classic_std_frame_to_linux);
    RUN_TEST(test_ext_rtr_flags_to_linux);
    RUN_TEST(test_fd_frame_roundtrip);
    RUN_TEST(test_from_linux_ext_and_error_frames);
    RUN_TEST(test_from_linux_rejects_odd_reads);
    RUN_TEST(test_invalid_frames_rejected);
    RUN_TEST(test_filters_for_node_ids);
    RUN_TEST(test_queue_fills_then_busy_and_drains_in_order);
    RUN_TEST(test_queued_frames_go_before_new_ones);
    RUN_TEST(test_write_error_is_io_and_counted);
    RUN_TEST(test_bad_frame_is_range_not_queued);
    RUN_TEST(test_error_frames_counted_not_returned);
    RUN_TEST(test_bus_off_faults_send_until_traffic_returns);
    RUN_TEST(test_error_frame_data_reaches_the_counters);
    RUN_TEST(test_recv_bounded_under_error_storm);
    RUN_TEST(test_open_missing_interface_fails_with_message);
    RUN_TEST(test_open_bad_arguments);
    return UNITY_END();
}
