/* stm32f4_can: see stm32f4_can.h. */
#include "stm32f4_can.h"

#define BRP_MAX 1024u
#define BS1_MAX 16u
#define BS2_MAX 8u
#define CLASSIC_MAX_LEN 8u
#define STD_ID_MAX 0x7FFu
#define EXT_ID_MASK 0x1FFFFFFFu
#define MAILBOXES 3u
#define FILTER_BANKS_USED (STM32_CAN_FILTER_IDS / 2u)
#define FILTER_BANK_MASK ((1u << FILTER_BANKS_USED) - 1u)

/* BS2 for tq quanta and the sample point target, within the field limits. */
static bool split(uint32_t tq, uint32_t *bs1, uint32_t *bs2)
{
    uint32_t b2 = (tq * (1000u - STM32_CAN_SAMPLE_PERMILLE) + 500u) / 1000u;
    if (b2 < 1u) {
        b2 = 1u;
    }
    if (b2 > BS2_MAX) {
        b2 = BS2_MAX;
    }
    if (tq - 1u - b2 > BS1_MAX) { /* sample point as late as BS1 allows */
        b2 = tq - 1u - BS1_MAX;
    }
    if (b2 < 1u || b2 > BS2_MAX || tq - 1u - b2 < 1u) {
        return false;
    }
    *bs1 = tq - 1u - b2;
    *bs2 = b2;
    return true;
}

/* |sample point - target| x 1000 x tq: compared across candidates as
 * fractions (err_a / tq_a < err_b / tq_b), so no rounding decides. */
static uint32_t sample_error_scaled(uint32_t tq, uint32_t bs1)
{
    uint32_t sp = 1000u * (1u + bs1);
    uint32_t target = STM32_CAN_SAMPLE_PERMILLE * tq;
    return sp > target ? sp - target : target - sp;
}

bool stm32_can_timing(uint32_t pclk1_hz, uint32_t bitrate, stm32_can_timing_t *out)
{
    bool found = false;
    uint32_t best_err = 0u, best_tq = 1u;
    for (uint32_t brp = 1u; brp <= BRP_MAX && bitrate != 0u; brp++) {
        uint64_t per_bit = (uint64_t)brp * bitrate;
        if (pclk1_hz % per_bit != 0u) {
            continue;
        }
        uint32_t tq = (uint32_t)(pclk1_hz / per_bit);
        uint32_t bs1, bs2;
        if (tq < STM32_CAN_TQ_MIN || tq > STM32_CAN_TQ_MAX || !split(tq, &bs1, &bs2)) {
            continue;
        }
        uint32_t err = sample_error_scaled(tq, bs1);
        /* Strictly better only: ties keep the smaller prescaler (more quanta). */
        if (!found || (uint64_t)err * best_tq < (uint64_t)best_err * tq) {
            found = true;
            best_err = err;
            best_tq = tq;
            out->brp = brp;
            out->bs1 = bs1;
            out->bs2 = bs2;
            out->sjw = 1u;
        }
    }
    return found;
}

uint32_t stm32_can_btr(const stm32_can_timing_t *t)
{
    return ((t->sjw - 1u) << STM32_CAN_BTR_SJW_POS) | ((t->bs2 - 1u) << STM32_CAN_BTR_TS2_POS) |
           ((t->bs1 - 1u) << STM32_CAN_BTR_TS1_POS) | ((t->brp - 1u) & STM32_CAN_BTR_BRP_MASK);
}

int stm32_can_init(stm32_can_drv_t *drv, const stm32_can_config_t *cfg)
{
    drv->cfg = *cfg;
    drv->txq_head = 0u;
    drv->txq_count = 0u;
    drv->counters = (hal_counters_t){0};
    drv->bus_off = false;
    drv->running = false;
    if (!stm32_can_timing(cfg->pclk1_hz, cfg->bitrate, &drv->timing)) {
        return HAL_ERR_RANGE;
    }
    stm32_can_t *can = cfg->can;
    /* Leave sleep (the reset state) for initialization mode. */
    STM32_WR(can->MCR, (STM32_RD(can->MCR) & ~STM32_CAN_MCR_SLEEP) | STM32_CAN_MCR_INRQ);
    if (!stm32_wait(&can->MSR, STM32_CAN_MSR_INAK | STM32_CAN_MSR_SLAK, STM32_CAN_MSR_INAK,
                    cfg->ready_polls)) {
        return HAL_ERR_IO;
    }
    STM32_WR(can->MCR, STM32_CAN_MCR_INRQ | STM32_CAN_MCR_ABOM | STM32_CAN_MCR_TXFP |
                           STM32_CAN_MCR_DBF);
    STM32_WR(can->BTR, stm32_can_btr(&drv->timing) |
                           (cfg->loopback ? (STM32_CAN_BTR_LBKM | STM32_CAN_BTR_SILM) : 0u));
    STM32_SET(can->FMR, STM32_CAN_FMR_FINIT);
    STM32_WR(can->FA1R, 0u);
    STM32_CLR(can->FMR, STM32_CAN_FMR_FINIT);
    STM32_WR(can->IER, STM32_CAN_IER_TMEIE);
    STM32_CLR(can->MCR, STM32_CAN_MCR_INRQ);
    if (!stm32_wait(&can->MSR, STM32_CAN_MSR_INAK, 0u, cfg->ready_polls)) {
        return HAL_ERR_IO;
    }
    drv->running = true;
    return HAL_OK;
}

/* 32-bit filter layout = the RIxR layout: STID at 31:21 or EXID at 31:3
 * with IDE, RTR = 0 (remote frames are not commands). */
static uint32_t filter_entry(uint32_t id)
{
    if ((id & HAL_CAN_ID_EXT_BIT) != 0u) {
        return ((id & EXT_ID_MASK) << STM32_CAN_IR_EXID_POS) | STM32_CAN_IR_IDE;
    }
    return (id & STD_ID_MAX) << STM32_CAN_IR_STID_POS;
}

int stm32_can_set_filter(void *ctx, const uint32_t *ids, size_t n)
{
    stm32_can_drv_t *drv = ctx;
    if (n > STM32_CAN_FILTER_IDS || (n > 0u && ids == NULL)) {
        return HAL_ERR_RANGE;
    }
    for (size_t i = 0; i < n; i++) {
        uint32_t limit = (ids[i] & HAL_CAN_ID_EXT_BIT) != 0u ? EXT_ID_MASK : STD_ID_MAX;
        if ((ids[i] & ~HAL_CAN_ID_EXT_BIT) > limit) {
            return HAL_ERR_RANGE;
        }
    }
    stm32_can_t *can = drv->cfg.can;
    STM32_SET(can->FMR, STM32_CAN_FMR_FINIT);
    STM32_CLR(can->FA1R, FILTER_BANK_MASK);
    STM32_SET(can->FS1R, FILTER_BANK_MASK);   /* 32-bit scale */
    STM32_CLR(can->FFA1R, FILTER_BANK_MASK);  /* FIFO 0 */
    uint32_t active = 0u;
    if (n == 0u) {
        STM32_CLR(can->FM1R, 1u);               /* mask mode, mask 0: everything */
        STM32_WR(can->FR[0][0], 0u);
        STM32_WR(can->FR[0][1], 0u);
        active = 1u;
    } else {
        STM32_SET(can->FM1R, FILTER_BANK_MASK); /* identifier list, two per bank */
        for (uint32_t bank = 0; 2u * bank < n; bank++) {
            size_t i = 2u * bank;
            /* A list slot cannot be empty: an odd count repeats the last id. */
            STM32_WR(can->FR[bank][0], filter_entry(ids[i]));
            STM32_WR(can->FR[bank][1], filter_entry(ids[i + 1u < n ? i + 1u : i]));
            active |= 1u << bank;
        }
    }
    STM32_SET(can->FA1R, active);
    STM32_CLR(can->FMR, STM32_CAN_FMR_FINIT);
    return HAL_OK;
}

static uint32_t le32(const uint8_t *p)
{
    return (uint32_t)p[0] | ((uint32_t)p[1] << 8) | ((uint32_t)p[2] << 16) |
           ((uint32_t)p[3] << 24);
}

static void put_le32(uint8_t *p, uint32_t v)
{
    p[0] = (uint8_t)v;
    p[1] = (uint8_t)(v >> 8);
    p[2] = (uint8_t)(v >> 16);
    p[3] = (uint8_t)(v >> 24);
}

static int free_mailbox(const stm32_can_t *can)
{
    uint32_t tsr = STM32_RD(can->TSR);
    for (uint32_t i = 0; i < MAILBOXES; i++) {
        if ((tsr & (STM32_CAN_TSR_TME0 << i)) != 0u) {
            return (int)i;
        }
    }
    return -1;
}

/* The low n bytes of a word (n <= 4). */
static uint32_t low_bytes(uint32_t w, uint32_t n)
{
    return n >= 4u ? w : w & ((1u << (8u * n)) - 1u);
}

/* f->len <= 8 (checked by the caller).  The data words read all 8 bytes of
 * f->data and keep the first len: no byte copy per frame. */
static stm32_can_tx_words_t tx_words(const hal_can_frame_t *f)
{
    stm32_can_tx_words_t w;
    w.tir = ((f->flags & HAL_CAN_FLAG_EXT) != 0u)
                ? (((f->id & EXT_ID_MASK) << STM32_CAN_IR_EXID_POS) | STM32_CAN_IR_IDE)
                : ((f->id & STD_ID_MAX) << STM32_CAN_IR_STID_POS);
    if ((f->flags & HAL_CAN_FLAG_RTR) != 0u) {
        w.tir |= STM32_CAN_IR_RTR;
    }
    w.tdtr = f->len;
    w.tdlr = low_bytes(le32(&f->data[0]), f->len);
    w.tdhr = f->len > 4u ? low_bytes(le32(&f->data[4]), f->len - 4u) : 0u;
    return w;
}

static void load_mailbox(stm32_can_t *can, int box, const stm32_can_tx_words_t *w)
{
    stm32_can_tx_mailbox_t *mb = &can->TX[box];
    STM32_WR(mb->TDTR, w->tdtr);
    STM32_WR(mb->TDLR, w->tdlr);
    STM32_WR(mb->TDHR, w->tdhr);
    STM32_WR(mb->TIR, w->tir | STM32_CAN_TIR_TXRQ); /* the request goes last */
}

int stm32_can_send(void *ctx, const hal_can_frame_t *frame)
{
    stm32_can_drv_t *drv = ctx;
    if (frame->len > CLASSIC_MAX_LEN ||
        (frame->flags & (HAL_CAN_FLAG_FD | HAL_CAN_FLAG_ERR)) != 0u ||
        ((frame->flags & HAL_CAN_FLAG_EXT) == 0u && frame->id > STD_ID_MAX)) {
        return HAL_ERR_RANGE;
    }
    stm32_can_t *can = drv->cfg.can;
    if (!drv->running || (STM32_RD(can->ESR) & STM32_CAN_ESR_BOFF) != 0u) {
        return HAL_ERR_FAULT;
    }
    const stm32_can_tx_words_t w = tx_words(frame); /* before the critical section */
    int rc = HAL_OK;
    uint32_t primask = stm32_irq_save();
    int box = drv->txq_count == 0u ? free_mailbox(can) : -1; /* keep the order */
    if (box >= 0) {
        load_mailbox(can, box, &w);
    } else if (drv->txq_count < STM32_CAN_TXQ) {
        drv->txq[(drv->txq_head + drv->txq_count) % STM32_CAN_TXQ] = w;
        drv->txq_count++;
    } else {
        drv->counters.can_tx_dropped++;
        rc = HAL_ERR_BUSY;
    }
    stm32_irq_restore(primask);
    return rc;
}

static void read_errors(stm32_can_drv_t *drv)
{
    stm32_can_t *can = drv->cfg.can;
    uint32_t esr = STM32_RD(can->ESR);
    bool off = (esr & STM32_CAN_ESR_BOFF) != 0u;
    if (off && !drv->bus_off) {
        drv->counters.can_bus_off++;
    }
    drv->bus_off = off;
    uint32_t lec = (esr & STM32_CAN_ESR_LEC_MASK) >> STM32_CAN_ESR_LEC_POS;
    if (lec != 0u && lec != STM32_CAN_ESR_LEC_USER) {
        drv->counters.can_error_frames++;
        /* 7 is never written by hardware: the next error code shows a new error. */
        STM32_WR(can->ESR, STM32_CAN_ESR_LEC_USER << STM32_CAN_ESR_LEC_POS);
    }
    drv->counters.can_tx_error_count = (uint8_t)(esr >> STM32_CAN_ESR_TEC_POS);
    drv->counters.can_rx_error_count = (uint8_t)(esr >> STM32_CAN_ESR_REC_POS);
}

void stm32_can_tx_service(stm32_can_drv_t *drv)
{
    stm32_can_t *can = drv->cfg.can;
    uint32_t primask = stm32_irq_save();
    uint32_t tsr = STM32_RD(can->TSR);
    for (uint32_t i = 0; i < MAILBOXES; i++) {
        uint32_t rqcp = STM32_CAN_TSR_RQCP0 << (STM32_CAN_TSR_MAILBOX_SHIFT * i);
        if ((tsr & rqcp) != 0u) {
            if ((tsr & (STM32_CAN_TSR_TXOK0 << (STM32_CAN_TSR_MAILBOX_SHIFT * i))) != 0u) {
                drv->counters.can_tx_ok++;
            } else {
                drv->counters.can_tx_aborted++;
            }
            STM32_WR(can->TSR, rqcp); /* rc_w1: clears RQCP, TXOK, ALST, TERR */
        }
    }
    while (drv->txq_count > 0u) {
        int box = free_mailbox(can);
        if (box < 0) {
            break;
        }
        load_mailbox(can, box, &drv->txq[drv->txq_head]);
        drv->txq_head = (drv->txq_head + 1u) % STM32_CAN_TXQ;
        drv->txq_count--;
    }
    stm32_irq_restore(primask);
    read_errors(drv);
}

int stm32_can_recv(void *ctx, hal_can_frame_t *frame)
{
    stm32_can_drv_t *drv = ctx;
    stm32_can_t *can = drv->cfg.can;
    uint32_t rf = STM32_RD(can->RF0R);
    if ((rf & STM32_CAN_RFR_FOVR) != 0u) {
        drv->counters.can_rx_overruns++;
        STM32_WR(can->RF0R, STM32_CAN_RFR_FOVR | STM32_CAN_RFR_FULL); /* rc_w1 */
    }
    if ((rf & STM32_CAN_RFR_FMP_MASK) == 0u) {
        return HAL_ERR_NO_DATA;
    }
    const stm32_can_rx_fifo_t *mb = &can->RX[0];
    uint32_t rir = STM32_RD(mb->RIR);
    uint32_t dlc = STM32_RD(mb->RDTR) & STM32_CAN_DTR_DLC_MASK;
    uint8_t data[CLASSIC_MAX_LEN];
    put_le32(&data[0], STM32_RD(mb->RDLR));
    put_le32(&data[4], STM32_RD(mb->RDHR));
    STM32_WR(can->RF0R, STM32_CAN_RFR_RFOM); /* release: the next frame moves up */
    frame->flags = 0u;
    if ((rir & STM32_CAN_IR_IDE) != 0u) {
        frame->id = (rir >> STM32_CAN_IR_EXID_POS) & EXT_ID_MASK;
        frame->flags |= HAL_CAN_FLAG_EXT;
    } else {
        frame->id = rir >> STM32_CAN_IR_STID_POS;
    }
    if ((rir & STM32_CAN_IR_RTR) != 0u) {
        frame->flags |= HAL_CAN_FLAG_RTR;
    }
    frame->len = (uint8_t)(dlc > CLASSIC_MAX_LEN ? CLASSIC_MAX_LEN : dlc);
    for (uint32_t i = 0; i < CLASSIC_MAX_LEN; i++) {
        frame->data[i] = i < frame->len ? data[i] : 0u;
    }
    drv->counters.can_rx++;
    return HAL_OK;
}

void stm32_can_counters(void *ctx, hal_counters_t *out)
{
    const stm32_can_drv_t *drv = ctx;
    *out = drv->counters;
}
