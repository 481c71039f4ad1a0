/*
 * hd_stm32f4_bench.elf: instruction counts of this port's interrupt
 * bodies, run on QEMU's netduinoplus2 with tools/qemu-plugin (tools/target
 * budget --board stm32f4).
 *
 * The board code and drivers are the ones the board images run, compiled
 * the same way, but their register blocks are RAM (stm32_periph_t): before
 * each call the bench puts the registers in the state the hardware would
 * show (update flag set, conversion complete with a sample in JDR1,
 * encoder counts moved, transmit mailboxes empty, receive FIFO as the
 * section says).  Sections (64 calls each, "section LABEL STATES" on the
 * console, then the plugin's intervals between hd_mark_begin/hd_mark_end):
 *   empty, loop   marker overhead and the counter's closed-form check
 *   tick          stm32_board_tick: CAN service + hd_fw_isr (ADC, encoders,
 *                 filter, telemetry frames into the mailboxes)
 *   tickrx        the same with a command frame waiting in FIFO 0 every
 *                 tick (RAM cannot show the FIFO refilling after a release,
 *                 so one frame per tick)
 *   tickadc       the same with the conversion missing: the ADC wait runs
 *                 to its bound (STM32_BOARD_ADC_POLLS) and the fault is set
 *   cantx         the CAN transmit interrupt moving three queued frames
 *                 into the mailboxes
 * With the argument "tickrate" it only counts the update events of TIM2,
 * programmed by stm32_tick_init for QEMU's timer clock, in 20 ms of SysTick
 * time (SysTick runs on the 168 MHz core clock in QEMU) and prints
 * "tickrate: N" and "per ms: 20".
 */
#include <stdint.h>
#include <string.h>

#include "board.h"
#include "board_io.h"
#include "hd_can_proto.h"
#include "hd_fw.h"
#include "hd_mark.h"
#include "semihost.h"
#include "stm32f4_board.h"
#include "stm32f4_startup.h"

#define CALLS 64u

static stm32_rcc_t r_rcc;
static stm32_flash_t r_flash;
static stm32_iwdg_t r_iwdg;
static stm32_tim_t r_tick, r_enc_m, r_enc_o;
static stm32_adc_t r_adc;
static stm32_adc_common_t r_adc_common;
static stm32_can_t r_can;
static uint8_t r_nvm[2u * 16384u];

static stm32_board_t g_board;
static hd_fw_t g_fw;
static hal_t g_hal;
static uint32_t g_cycle_counter; /* DWT CYCCNT as the hardware would show it */

/* The board's clock arithmetic on a cycle counter set per tick (QEMU has
 * no DWT), so the counted tick includes it. */
static uint64_t bench_time_us(void *ctx)
{
    stm32_board_t *b = ctx;
    return stm32_cycle_clock_advance(&b->cycles, g_cycle_counter);
}

static void section(const char *label, uint32_t states)
{
    sh_puts("section ");
    sh_puts(label);
    board_print_u32(" ", states);
}

static void calibration_section(const char *label)
{
    section(label, 0u);
}

/* The drivers configured as stm32_board_boot would, on RAM registers
 * (handshakes cannot run against RAM: CAN is marked running). */
static void setup(void)
{
    const stm32_board_def_t *def = &stm32_board_odrive_v3;
    stm32_periph_t p;
    memset(&p, 0, sizeof p);
    p.rcc = &r_rcc;
    p.flash = &r_flash;
    p.iwdg = &r_iwdg;
    p.tick = &r_tick;
    p.adc = &r_adc;
    p.adc_common = &r_adc_common;
    p.motor_enc = &r_enc_m;
    p.output_enc = &r_enc_o;
    p.can = &r_can;
    p.nvm_mem = r_nvm;
    memset(r_nvm, 0xFF, sizeof r_nvm);
    g_board.def = def;
    g_board.p = p;
    stm32_clock_hsi(&g_board.clock);
    (void)stm32_tick_init(p.tick, 168000000u, STM32_BOARD_TICK_HZ, 0xFFFFu);
    stm32_adc_config_t ac = {.adc = p.adc, .common = p.adc_common, .channel = def->adc_channel,
                             .jextsel = def->adc_jextsel, .sample_code = 3u, .adcpre = 1u,
                             .midscale_counts = 2048u, .ready_polls = STM32_BOARD_ADC_POLLS};
    (void)stm32_adc_init(&g_board.adc, &ac);
    stm32_encoder_config_t ec = {.tim = p.motor_enc, .counter_bits = 16u, .filter = 6u};
    stm32_encoder_init(&g_board.motor_enc, &ec);
    ec.tim = p.output_enc;
    stm32_encoder_init(&g_board.output_enc, &ec);
    r_can.MSR = STM32_CAN_MSR_INAK;
    stm32_can_config_t cc = {.can = p.can, .pclk1_hz = 42000000u, .bitrate = 1000000u,
                             .ready_polls = 4u, .loopback = false};
    (void)stm32_can_init(&g_board.can, &cc);
    g_board.can.running = true;
    stm32_flash_config_t fc = {.regs = p.flash, .mem = p.nvm_mem, .first_sector = 1u,
                               .sector_count = 2u, .sector_bytes = 16384u,
                               .erase_polls = 4u, .program_polls = 4u};
    stm32_flash_init(&g_board.flash, &fc);
    stm32_board_bind(&g_board, &g_hal);
    g_board.cycles = (stm32_cycle_clock_t){.cycles_per_us = STM32_BOARD_SYSCLK_HZ / 1000000u};
    g_hal.clock.time_us = bench_time_us;
    hd_fw_config_t cfg;
    hd_fw_config_default(&cfg);
    if (hd_fw_init(&g_fw, &g_hal, &cfg) != HD_FW_OK) {
        sh_exit(BOARD_EXIT_INIT);
    }
}

/* The registers as the hardware shows them at tick k. */
static void hardware_state(uint32_t k, bool converted, uint32_t rx_frames)
{
    r_tick.SR = STM32_TIM_SR_UIF;
    r_adc.SR = converted ? STM32_ADC_SR_JEOC : 0u;
    int32_t counts = 1000 + (int32_t)((k * 37u) % 200u);
    r_adc.JDR[0] = (uint32_t)(uint16_t)(int16_t)counts;
    r_enc_m.CNT = (r_enc_m.CNT + 107u) & 0xFFFFu; /* ~156 rad/s at 4096 counts/rev */
    r_enc_o.CNT = (r_enc_o.CNT + 1u) & 0xFFFFu;
    r_can.TSR = STM32_CAN_TSR_TME0 | (STM32_CAN_TSR_TME0 << 1) | (STM32_CAN_TSR_TME0 << 2);
    r_can.ESR = 0u;
    r_can.RF0R = rx_frames > 3u ? 3u : rx_frames;
    g_cycle_counter = k * HD_FW_TS_US * (STM32_BOARD_SYSCLK_HZ / 1000000u);
}

static void command_in_fifo(void)
{
    hd_can_cmd_t c;
    memset(&c, 0, sizeof c);
    c.opcode = HD_CMD_GET_PARAM;
    c.arg.get_param.id = 1u;
    hal_can_frame_t f;
    hd_can_encode_cmd(1u, &c, &f);
    r_can.RX[0].RIR = ((f.id & 0x1FFFFFFFu) << STM32_CAN_IR_EXID_POS) | STM32_CAN_IR_IDE;
    r_can.RX[0].RDTR = f.len;
    r_can.RX[0].RDLR = (uint32_t)f.data[0] | ((uint32_t)f.data[1] << 8) |
                       ((uint32_t)f.data[2] << 16) | ((uint32_t)f.data[3] << 24);
    r_can.RX[0].RDHR = (uint32_t)f.data[4] | ((uint32_t)f.data[5] << 8) |
                       ((uint32_t)f.data[6] << 16) | ((uint32_t)f.data[7] << 24);
}

static void run_ticks(const char *label, uint32_t states, bool converted, uint32_t rx)
{
    setup();
    if (rx != 0u) {
        command_in_fifo();
    }
    section(label, states);
    for (uint32_t k = 0; k < CALLS; k++) {
        hardware_state(k, converted, rx);
        stm32_board_tick(&g_board, &g_fw);
        (void)hd_fw_background(&g_fw); /* between ticks, as the main loop */
    }
    hd_mark_section();
}

static void run_can_tx(void)
{
    setup();
    section("cantx:odrive-v3", 0u);
    hal_can_frame_t f;
    memset(&f, 0, sizeof f);
    f.id = 0x01D00101u;
    f.flags = HAL_CAN_FLAG_EXT;
    f.len = 8u;
    for (uint32_t k = 0; k < CALLS; k++) {
        r_can.TSR = 0u; /* mailboxes busy: the frames queue */
        for (int i = 0; i < 3; i++) {
            (void)stm32_can_send(&g_board.can, &f);
        }
        r_can.TSR = STM32_CAN_TSR_TME0 | (STM32_CAN_TSR_TME0 << 1) | (STM32_CAN_TSR_TME0 << 2);
        hd_mark_begin();
        stm32_can_tx_service(&g_board.can);
        hd_mark_end();
    }
    hd_mark_section();
}

#define SYST_CSR (*(volatile uint32_t *)0xE000E010u)
#define SYST_RVR (*(volatile uint32_t *)0xE000E014u)
#define SYST_CVR (*(volatile uint32_t *)0xE000E018u)
#define SYST_CSR_ENABLE_CORE_CLOCK 0x5u
#define SYST_CSR_COUNTFLAG (1u << 16)
#define QEMU_CORE_HZ 168000000u
#define QEMU_TIM_CLOCK_HZ 1000000000u
#define RATE_WINDOW_MS 20u

static int tick_rate(void)
{
    stm32_tim_t *tim2 = (stm32_tim_t *)STM32_TIM2_BASE;
    (void)stm32_tick_init(tim2, QEMU_TIM_CLOCK_HZ, STM32_BOARD_TICK_HZ, 0xFFFFu);
    SYST_RVR = QEMU_CORE_HZ / 1000u - 1u;
    SYST_CVR = 0u;
    SYST_CSR = SYST_CSR_ENABLE_CORE_CLOCK; /* no interrupt: polled */
    stm32_tick_start(tim2);
    STM32_WR(tim2->EGR, STM32_TIM_EGR_UG); /* QEMU arms its timer on this write */
    /* Count from the first SysTick period on: both timers then tick once
     * per millisecond with a phase below one period between them. */
    while ((SYST_CSR & SYST_CSR_COUNTFLAG) == 0u) {
    }
    (void)stm32_tick_ack(tim2);
    uint32_t ms = 0u, ticks = 0u;
    while (ms < RATE_WINDOW_MS) { /* ends: SysTick counts on its own */
        if (SYST_CSR & SYST_CSR_COUNTFLAG) {
            ms++;
        }
        if (stm32_tick_ack(tim2)) {
            ticks++;
        }
    }
    stm32_tick_stop(tim2);
    board_print_u32("tickrate: ", ticks);
    board_print_u32("per ms: ", RATE_WINDOW_MS);
    return BOARD_EXIT_OK;
}

int main(void)
{
    char *argv[2];
    if (board_args(argv, 2) == 2 && strcmp(argv[1], "tickrate") == 0) {
        return tick_rate();
    }
    hd_mark_calibration(calibration_section);

    hd_fw_config_t cfg;
    hd_fw_config_default(&cfg);
    uint32_t states = 2u * cfg.kf.block_count + (cfg.kf.offset_enabled ? 1u : 0u);
    run_ticks("tick:odrive-v3", states, true, 0u);
    run_ticks("tickrx:odrive-v3", states, true, 1u);
    run_ticks("tickadc:odrive-v3", states, false, 0u);
    run_can_tx();
    sh_puts("bench: done\n");
    return BOARD_EXIT_OK;
}

void board_early_init(void)
{
}
