/* model_can: see model_can.h. */
#include "model_can.h"

#include <string.h>

#define OFF(field) offsetof(stm32_can_t, field)
#define MAILBOX_OFF(i) (OFF(TX) + (i) * sizeof(stm32_can_tx_mailbox_t))

/* Reset values (RM0090 32.9). */
#define MCR_RESET 0x00010002u
#define MSR_RESET 0x00000C02u
#define TSR_RESET 0x1C000000u
#define BTR_RESET 0x01230000u
#define FMR_RESET 0x2A1C0E01u

static void violation(can_model_t *m, const char *what)
{
    m->violations++;
    m->last_violation = what;
}

static uint32_t tme(uint32_t i)
{
    return 1u << (26u + i);
}

static void update_esr(can_model_t *m)
{
    uint32_t lec = m->regs.ESR & STM32_CAN_ESR_LEC_MASK;
    uint32_t esr = lec | (m->tec << STM32_CAN_ESR_TEC_POS) | (m->rec << STM32_CAN_ESR_REC_POS);
    if (m->tec >= 96u || m->rec >= 96u) {
        esr |= STM32_CAN_ESR_EWGF;
    }
    if (m->tec >= 128u || m->rec >= 128u) {
        esr |= STM32_CAN_ESR_EPVF;
    }
    if (m->boff) {
        esr |= STM32_CAN_ESR_BOFF;
    }
    m->regs.ESR = esr;
}

/* The mode the MCR bits ask for. */
static can_mode_t requested(const can_model_t *m)
{
    if ((m->regs.MCR & STM32_CAN_MCR_SLEEP) != 0u) {
        return CAN_MODE_SLEEP;
    }
    return (m->regs.MCR & STM32_CAN_MCR_INRQ) != 0u ? CAN_MODE_INIT : CAN_MODE_NORMAL;
}

static void apply_mode(can_model_t *m)
{
    can_mode_t want = requested(m);
    if (want == CAN_MODE_NORMAL && m->bus_dominant) {
        return; /* 11 recessive bits never come */
    }
    m->mode = want;
    m->regs.MSR &= ~(STM32_CAN_MSR_INAK | STM32_CAN_MSR_SLAK);
    if (want == CAN_MODE_INIT) {
        m->regs.MSR |= STM32_CAN_MSR_INAK;
    } else if (want == CAN_MODE_SLEEP) {
        m->regs.MSR |= STM32_CAN_MSR_SLAK;
    }
}

static void encode_ir(const hal_can_frame_t *f, uint32_t *ir, uint32_t *dtr, uint32_t *dl,
                      uint32_t *dh)
{
    *ir = (f->flags & HAL_CAN_FLAG_EXT) ? ((f->id << STM32_CAN_IR_EXID_POS) | STM32_CAN_IR_IDE)
                                        : (f->id << STM32_CAN_IR_STID_POS);
    if (f->flags & HAL_CAN_FLAG_RTR) {
        *ir |= STM32_CAN_IR_RTR;
    }
    *dtr = f->len;
    *dl = (uint32_t)f->data[0] | ((uint32_t)f->data[1] << 8) | ((uint32_t)f->data[2] << 16) |
          ((uint32_t)f->data[3] << 24);
    *dh = (uint32_t)f->data[4] | ((uint32_t)f->data[5] << 8) | ((uint32_t)f->data[6] << 16) |
          ((uint32_t)f->data[7] << 24);
}

static hal_can_frame_t decode_mailbox(const stm32_can_tx_mailbox_t *mb)
{
    hal_can_frame_t f;
    memset(&f, 0, sizeof f);
    uint32_t tir = mb->TIR;
    if (tir & STM32_CAN_IR_IDE) {
        f.id = (tir >> STM32_CAN_IR_EXID_POS) & 0x1FFFFFFFu;
        f.flags |= HAL_CAN_FLAG_EXT;
    } else {
        f.id = tir >> STM32_CAN_IR_STID_POS;
    }
    if (tir & STM32_CAN_IR_RTR) {
        f.flags |= HAL_CAN_FLAG_RTR;
    }
    f.len = (uint8_t)(mb->TDTR & 0xFu);
    for (int i = 0; i < 4; i++) {
        f.data[i] = (uint8_t)(mb->TDLR >> (8 * i));
        f.data[4 + i] = (uint8_t)(mb->TDHR >> (8 * i));
    }
    return f;
}

static void show_fifo_head(can_model_t *m)
{
    if (m->fifo_count == 0u) {
        return;
    }
    uint32_t ir, dtr, dl, dh;
    encode_ir(&m->fifo[0], &ir, &dtr, &dl, &dh);
    m->regs.RX[0].RIR = ir;
    m->regs.RX[0].RDTR = dtr;
    m->regs.RX[0].RDLR = dl;
    m->regs.RX[0].RDHR = dh;
}

static uint32_t read_reg(reg_model_t *rm, size_t off)
{
    can_model_t *m = (can_model_t *)rm;
    if (off == OFF(MSR) && m->ack_pending && !m->no_clock) {
        if (m->ack_left > 0u) {
            m->ack_left--;
        }
        if (m->ack_left == 0u) {
            m->ack_pending = false;
            apply_mode(m);
            m->ack_pending = requested(m) != m->mode; /* still waiting (dominant bus) */
        }
    }
    if (off == OFF(TSR)) {
        uint32_t code = 0u;
        for (uint32_t i = 0; i < 3u; i++) {
            if (m->regs.TSR & tme(i)) {
                code = i;
                break;
            }
        }
        m->regs.TSR = (m->regs.TSR & ~(3u << 24)) | (code << 24);
    }
    if (off == OFF(RF0R)) {
        m->regs.RF0R = (m->regs.RF0R & ~STM32_CAN_RFR_FMP_MASK) | (uint32_t)m->fifo_count;
    }
    return *reg_at(&m->regs, off);
}

static void write_mailbox(can_model_t *m, size_t off, uint32_t v)
{
    size_t rel = off - OFF(TX);
    uint32_t box = (uint32_t)(rel / sizeof(stm32_can_tx_mailbox_t));
    size_t reg = rel % sizeof(stm32_can_tx_mailbox_t);
    if ((m->regs.TSR & tme(box)) == 0u) {
        violation(m, "write to a mailbox with a pending request");
        return;
    }
    *reg_at(&m->regs, off) = v;
    if (reg == offsetof(stm32_can_tx_mailbox_t, TIR) && (v & STM32_CAN_TIR_TXRQ)) {
        m->regs.TSR &= ~tme(box);
        m->tx_order[box] = ++m->tx_seq;
    }
}

static void write_reg(reg_model_t *rm, size_t off, uint32_t v)
{
    can_model_t *m = (can_model_t *)rm;
    if (off == OFF(MCR)) {
        m->regs.MCR = v & 0x000180FFu;
        m->ack_pending = requested(m) != m->mode;
        m->ack_left = m->ack_reads;
    } else if (off == OFF(MSR) || off == OFF(RF1R) || off == OFF(IER)) {
        *reg_at(&m->regs, off) = v; /* w1c details of MSR not used by the driver */
    } else if (off == OFF(TSR)) {
        for (uint32_t i = 0; i < 3u; i++) {
            if (v & (STM32_CAN_TSR_RQCP0 << (8u * i))) {
                m->regs.TSR &= ~(0xFu << (8u * i)); /* RQCP, TXOK, ALST, TERR */
            }
        }
    } else if (off == OFF(RF0R)) {
        if ((v & STM32_CAN_RFR_RFOM) && m->fifo_count > 0u) {
            memmove(&m->fifo[0], &m->fifo[1], (m->fifo_count - 1u) * sizeof m->fifo[0]);
            m->fifo_count--;
            m->regs.RF0R &= ~STM32_CAN_RFR_FULL;
            show_fifo_head(m);
        }
        m->regs.RF0R &= ~(v & (STM32_CAN_RFR_FULL | STM32_CAN_RFR_FOVR));
    } else if (off == OFF(ESR)) {
        m->regs.ESR = (m->regs.ESR & ~STM32_CAN_ESR_LEC_MASK) | (v & STM32_CAN_ESR_LEC_MASK);
    } else if (off == OFF(BTR)) {
        if (m->mode != CAN_MODE_INIT) {
            violation(m, "BTR written outside initialization mode");
            return;
        }
        m->regs.BTR = v;
    } else if (off >= OFF(TX) && off < OFF(RX)) {
        write_mailbox(m, off, v);
    } else if (off >= OFF(RX) && off < OFF(FMR)) {
        violation(m, "write to a receive mailbox");
    } else if (off == OFF(FMR) || off == OFF(FA1R)) {
        *reg_at(&m->regs, off) = v;
    } else if (off == OFF(FM1R) || off == OFF(FS1R) || off == OFF(FFA1R)) {
        if ((m->regs.FMR & STM32_CAN_FMR_FINIT) == 0u) {
            violation(m, "filter mode written outside filter initialization");
            return;
        }
        *reg_at(&m->regs, off) = v;
    } else if (off >= OFF(FR)) {
        uint32_t bank = (uint32_t)((off - OFF(FR)) / 8u);
        if ((m->regs.FMR & STM32_CAN_FMR_FINIT) == 0u && (m->regs.FA1R & (1u << bank))) {
            violation(m, "active filter bank written outside filter initialization");
            return;
        }
        *reg_at(&m->regs, off) = v;
    } else {
        violation(m, "write to a reserved address");
    }
}

void can_model_init(can_model_t *m)
{
    memset(m, 0, sizeof *m);
    m->rm.name = "bxCAN";
    m->rm.base = &m->regs;
    m->rm.size = sizeof m->regs;
    m->rm.read = read_reg;
    m->rm.write = write_reg;
    m->regs.MCR = MCR_RESET;
    m->regs.MSR = MSR_RESET;
    m->regs.TSR = TSR_RESET;
    m->regs.BTR = BTR_RESET;
    m->regs.FMR = FMR_RESET;
    m->mode = CAN_MODE_SLEEP;
    m->ack_reads = 3u;
    m->recovery_steps = 5u;
    m->inject_lec = 3u; /* acknowledgment error: nobody else on the bus */
    reg_model_add(&m->rm);
}

static int next_mailbox(const can_model_t *m)
{
    int best = -1;
    for (uint32_t i = 0; i < 3u; i++) {
        if (m->regs.TSR & tme(i)) {
            continue;
        }
        if (best < 0) {
            best = (int)i;
            continue;
        }
        if (m->regs.MCR & STM32_CAN_MCR_TXFP) {
            if (m->tx_order[i] < m->tx_order[best]) {
                best = (int)i;
            }
        } else if ((m->regs.TX[i].TIR >> 3) < (m->regs.TX[best].TIR >> 3)) {
            best = (int)i; /* lower identifier wins arbitration (approximation) */
        }
    }
    return best;
}

bool can_model_bus_step(can_model_t *m)
{
    if (m->mode != CAN_MODE_NORMAL) {
        return false;
    }
    if (m->boff) {
        if ((m->regs.MCR & STM32_CAN_MCR_ABOM) && --m->recovery_left == 0u) {
            m->boff = false;
            m->tec = 0u;
            m->rec = 0u;
        }
        update_esr(m);
        return false;
    }
    int box = next_mailbox(m);
    if (box < 0) {
        return false;
    }
    if (m->inject_errors > 0u) {
        m->inject_errors--;
        m->tec += 8u;
        m->regs.ESR = (m->regs.ESR & ~STM32_CAN_ESR_LEC_MASK) |
                      (m->inject_lec << STM32_CAN_ESR_LEC_POS);
        if (m->tec > 255u) {
            m->boff = true;
            m->tec = 255u;
            m->recovery_left = m->recovery_steps;
        }
        update_esr(m);
        return false; /* automatic retransmission: the request stays pending */
    }
    if (m->wire_count < CAN_MODEL_WIRE) {
        m->wire[m->wire_count++] = decode_mailbox(&m->regs.TX[box]);
    }
    m->regs.TSR |= (STM32_CAN_TSR_RQCP0 | STM32_CAN_TSR_TXOK0) << (8u * (uint32_t)box);
    m->regs.TSR |= tme((uint32_t)box);
    if (m->tec > 0u) {
        m->tec--;
    }
    m->regs.ESR &= ~STM32_CAN_ESR_LEC_MASK; /* a frame without error clears LEC */
    update_esr(m);
    return true;
}

/* One 16-bit filter value against a frame (RM0090 figure "filter bank
 * scale configuration"): STID[10:0] RTR IDE EXID[17:15]. */
static uint32_t as16(const hal_can_frame_t *f)
{
    uint32_t v;
    if (f->flags & HAL_CAN_FLAG_EXT) {
        v = ((f->id >> 18) << 5) | (1u << 3) | ((f->id >> 15) & 7u); /* IDE = bit 3 */
    } else {
        v = f->id << 5;
    }
    if (f->flags & HAL_CAN_FLAG_RTR) {
        v |= 1u << 4; /* RTR = bit 4 */
    }
    return v & 0xFFFFu;
}

static uint32_t as32(const hal_can_frame_t *f)
{
    uint32_t ir, dtr, dl, dh;
    encode_ir(f, &ir, &dtr, &dl, &dh);
    return ir & ~1u;
}

static bool bank_matches(const can_model_t *m, uint32_t b, const hal_can_frame_t *f)
{
    uint32_t r1 = m->regs.FR[b][0], r2 = m->regs.FR[b][1];
    bool list = (m->regs.FM1R >> b) & 1u;
    if ((m->regs.FS1R >> b) & 1u) {
        uint32_t v = as32(f);
        return list ? (v == r1 || v == r2) : ((v & r2) == (r1 & r2));
    }
    uint32_t v = as16(f);
    if (list) {
        return v == (r1 & 0xFFFFu) || v == (r1 >> 16) || v == (r2 & 0xFFFFu) || v == (r2 >> 16);
    }
    return ((v & (r1 >> 16)) == (r1 & (r1 >> 16) & 0xFFFFu)) ||
           ((v & (r2 >> 16)) == (r2 & (r2 >> 16) & 0xFFFFu));
}

bool can_model_deliver(can_model_t *m, const hal_can_frame_t *f)
{
    if (m->mode != CAN_MODE_NORMAL || (m->regs.FMR & STM32_CAN_FMR_FINIT)) {
        return false; /* filter initialization mode: reception deactivated */
    }
    bool hit = false;
    for (uint32_t b = 0; b < STM32_CAN_FILTER_BANKS && !hit; b++) {
        if (((m->regs.FA1R >> b) & 1u) && !((m->regs.FFA1R >> b) & 1u)) {
            hit = bank_matches(m, b, f);
        }
    }
    if (!hit) {
        return false;
    }
    if (m->fifo_count == 3u) {
        m->regs.RF0R |= STM32_CAN_RFR_FOVR; /* RFLM = 0: the last one is overwritten */
        m->fifo[2] = *f;
        m->rx_overwritten++;
    } else {
        m->fifo[m->fifo_count++] = *f;
        if (m->fifo_count == 3u) {
            m->regs.RF0R |= STM32_CAN_RFR_FULL;
        }
    }
    show_fifo_head(m);
    return true;
}
