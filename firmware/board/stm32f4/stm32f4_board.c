/* stm32f4_board: see stm32f4_board.h. */
#include "stm32f4_board.h"

#include "hd_mark.h"

/* The registers sit at the reference manual's fixed addresses: integer to
 * pointer casts are the point here. */
/* NOLINTBEGIN(performance-no-int-to-ptr) */
void stm32_periph_hw(const stm32_board_def_t *def, stm32_periph_t *out)
{
    out->rcc = (stm32_rcc_t *)STM32_RCC_BASE;
    out->flash = (stm32_flash_t *)STM32_FLASH_IF_BASE;
    out->iwdg = (stm32_iwdg_t *)STM32_IWDG_BASE;
    for (uint32_t i = 0; i < STM32_GPIO_PORTS; i++) {
        out->gpio[i] = (stm32_gpio_t *)(uintptr_t)(STM32_GPIOA_BASE + i * STM32_GPIO_STRIDE);
    }
    out->tick = (stm32_tim_t *)def->tick_base;
    out->adc = (stm32_adc_t *)STM32_ADC1_BASE;
    out->adc_common = (stm32_adc_common_t *)STM32_ADC_COMMON_BASE;
    out->motor_enc = (stm32_tim_t *)def->motor_enc_base;
    out->output_enc = def->output_enc_base != 0u ? (stm32_tim_t *)def->output_enc_base : NULL;
    out->can = (stm32_can_t *)STM32_CAN1_BASE;
    out->nvm_mem = (uint8_t *)(uintptr_t)(STM32_FLASH_MEM_BASE +
                                          def->nvm_first_sector * def->nvm_sector_bytes);
}
/* NOLINTEND(performance-no-int-to-ptr) */

static void cycle_clock_start(stm32_cycle_clock_t *c, uint32_t sysclk_hz)
{
    c->cycles_per_us = sysclk_hz >= 1000000u ? sysclk_hz / 1000000u : 1u;
    c->rem_cycles = 0u;
    c->us = 0u;
#if defined(__arm__)
    STM32_DEMCR |= STM32_DEMCR_TRCENA;
    STM32_DWT_CYCCNT = 0u;
    STM32_DWT_CTRL |= STM32_DWT_CTRL_CYCCNTENA;
#endif
    c->last = 0u;
}

uint64_t stm32_board_time_us(void *ctx)
{
    stm32_board_t *b = ctx;
#if defined(__arm__)
    uint32_t now = STM32_DWT_CYCCNT;
#else
    uint32_t now = b->cycles.last;
#endif
    return stm32_cycle_clock_advance(&b->cycles, now); /* called each tick */
}

uint64_t stm32_cycle_clock_advance(stm32_cycle_clock_t *c, uint32_t now)
{
    const uint32_t elapsed = (uint32_t)(now - c->last) + c->rem_cycles;
    c->last = now;
    c->us += elapsed / c->cycles_per_us;
    c->rem_cycles = elapsed % c->cycles_per_us;
    return c->us;
}

int stm32_board_encoder_read(void *ctx, hal_encoder_sample_t *out)
{
    stm32_board_t *b = ctx;
    out->motor_counts = stm32_encoder_counts(&b->motor_enc);
    out->has_output = b->p.output_enc != NULL;
    out->output_counts = out->has_output ? stm32_encoder_counts(&b->output_enc) : 0u;
    out->fault = false; /* quadrature has no error line */
    return HAL_OK;
}

void stm32_board_boot_info(void *ctx, hal_boot_info_t *out)
{
    stm32_board_t *b = ctx;
    *out = b->boot;
    b->boot.fault_valid = false; /* reported once */
}

void stm32_board_reboot(void *ctx)
{
    (void)ctx;
    stm32_reboot();
}

static void take_boot_info(stm32_board_t *b, stm32_fault_record_t *rec)
{
    b->boot = (hal_boot_info_t){0};
    b->boot.reset_cause = stm32_reset_cause(b->p.rcc);
    stm32_fault_record_t f;
    if (rec != NULL && stm32_fault_record_take(rec, &f)) {
        b->boot.fault_valid = true;
        b->boot.fault_pc = f.pc;
        b->boot.fault_lr = f.lr;
        b->boot.fault_cfsr = f.cfsr;
        b->boot.fault_hfsr = f.hfsr;
        b->boot.fault_addr = f.bfar != 0u ? f.bfar : f.mmfar;
    }
}

static void boot_encoders(stm32_board_t *b, const stm32_board_def_t *def)
{
    stm32_encoder_config_t m = {.tim = b->p.motor_enc, .counter_bits = def->motor_enc_bits,
                                .filter = 6u, .invert = false};
    stm32_encoder_init(&b->motor_enc, &m);
    if (b->p.output_enc != NULL) {
        stm32_encoder_config_t o = {.tim = b->p.output_enc, .counter_bits = def->output_enc_bits,
                                    .filter = 6u, .invert = false};
        stm32_encoder_init(&b->output_enc, &o);
    }
}

static void boot_nvm(stm32_board_t *b, const stm32_board_def_t *def)
{
    stm32_flash_config_t f = {.regs = b->p.flash, .mem = b->p.nvm_mem,
                              .first_sector = def->nvm_first_sector,
                              .sector_count = def->nvm_sectors,
                              .sector_bytes = def->nvm_sector_bytes,
                              .erase_polls = STM32_BOARD_ERASE_POLLS,
                              .program_polls = STM32_BOARD_PROGRAM_POLLS};
    stm32_flash_init(&b->flash, &f);
}

static int board_adc_read(void *ctx, hal_adc_sample_t *out)
{
    stm32_board_t *b = ctx;
    return stm32_adc_read(&b->adc, out);
}

void stm32_board_bind(stm32_board_t *b, hal_t *hal)
{
    *hal = (hal_t){0};
    hal->name = b->def->name;
    hal->sensors.ctx = b;
    hal->sensors.adc_read = board_adc_read;
    hal->sensors.encoder_read = stm32_board_encoder_read;
    hal->can.ctx = &b->can;
    hal->can.send = stm32_can_send;
    hal->can.recv = stm32_can_recv;
    hal->can.counters = stm32_can_counters;
    hal->can.set_rx_filter = stm32_can_set_filter;
    stm32_flash_bind(&b->flash, &hal->nvm);
    hal->clock.ctx = b;
    hal->clock.time_us = stm32_board_time_us;
    hal->system.ctx = b;
    hal->system.board_id = b->def->board_id;
    hal->system.boot_info = stm32_board_boot_info;
    hal->system.reboot = stm32_board_reboot;
}

uint32_t stm32_board_boot(stm32_board_t *b, const stm32_board_def_t *def,
                          const stm32_periph_t *p, stm32_fault_record_t *fault_rec, hal_t *hal)
{
    b->def = def;
    b->p = *p;
    b->init_errors = 0u;
    b->ticks = 0u;
    take_boot_info(b, fault_rec);
    stm32_clock_config_t cc = {.hse_hz = def->hse_hz, .sysclk_hz = STM32_BOARD_SYSCLK_HZ,
                               .ready_polls = STM32_BOARD_READY_POLLS};
    if (stm32_clock_init(p->rcc, p->flash, &cc, &b->clock) != 0u) {
        b->boot.reset_cause |= HAL_RESET_CLOCK;
    }
    cycle_clock_start(&b->cycles, b->clock.sysclk_hz);
    if (stm32_iwdg_start(p->iwdg, STM32_BOARD_IWDG_PR, STM32_BOARD_IWDG_RELOAD,
                         STM32_BOARD_READY_POLLS) != HAL_OK) {
        b->init_errors |= STM32_BOARD_INIT_IWDG;
    }
    STM32_SET(p->rcc->APB1ENR, def->apb1_enr);
    STM32_SET(p->rcc->APB2ENR, def->apb2_enr);
    (void)STM32_RD(p->rcc->APB2ENR); /* RM0090 6.3.x: a read after enabling a clock */
    if (stm32_gpio_setup(p->rcc, p->gpio, def->pins, def->pin_count) != 0) {
        b->init_errors |= STM32_BOARD_INIT_PINS;
    }
    uint32_t tick_clock = def->tick_on_apb2 ? b->clock.tim_apb2_hz : b->clock.tim_apb1_hz;
    if (stm32_tick_init(p->tick, tick_clock, STM32_BOARD_TICK_HZ, 0xFFFFu) != HAL_OK) {
        b->init_errors |= STM32_BOARD_INIT_TICK;
    }
    stm32_adc_config_t ac = {.adc = p->adc, .common = p->adc_common,
                             .channel = def->adc_channel, .jextsel = def->adc_jextsel,
                             .sample_code = 3u, /* 56 ADC clocks: bridge amplifier output */
                             .adcpre = 1u,      /* PCLK2 / 4 = 21 MHz (max 36) */
                             .midscale_counts = 2048u, .ready_polls = STM32_BOARD_ADC_POLLS};
    if (stm32_adc_init(&b->adc, &ac) != HAL_OK) {
        b->init_errors |= STM32_BOARD_INIT_ADC;
    }
    boot_encoders(b, def);
    stm32_can_config_t can = {.can = p->can, .pclk1_hz = b->clock.pclk1_hz,
                              .bitrate = def->can_bitrate, .ready_polls = STM32_BOARD_CAN_POLLS,
                              .loopback = false};
    if (stm32_can_init(&b->can, &can) != HAL_OK) {
        b->init_errors |= STM32_BOARD_INIT_CAN;
    }
    boot_nvm(b, def);
    stm32_board_bind(b, hal);
    b->boot.init_errors = b->init_errors; /* INFO BOARD_INIT_ERRORS */
    return b->init_errors;
}

static void nvic_enable(uint32_t irq, uint8_t priority)
{
#if defined(__arm__)
    STM32_NVIC_IPR[irq] = (uint8_t)(priority << 4); /* 4 priority bits */
    STM32_NVIC_ISER[irq / 32u] = 1u << (irq % 32u);
#else
    (void)irq;
    (void)priority;
#endif
}

void stm32_board_start(stm32_board_t *b)
{
    nvic_enable(b->def->tick_irq, 1u);          /* the tick preempts CAN service */
    nvic_enable(STM32_IRQ_CAN1_TX, 2u);
    stm32_tick_start(b->p.tick);
}

void stm32_board_tick(stm32_board_t *b, hd_fw_t *fw)
{
    if (!stm32_tick_ack(b->p.tick)) {
        return;
    }
    hd_mark_begin();
    stm32_can_tx_service(&b->can);
    hd_fw_isr(fw);
    hd_mark_end();
    b->ticks = b->ticks + 1u;
}

/* --------------------------------------------------------- pin table */

static void put_u32(void (*put)(void *, const char *), void *ctx, uint32_t v)
{
    char d[11];
    int n = 10;
    d[n] = '\0';
    do {
        d[--n] = (char)('0' + v % 10u);
        v /= 10u;
    } while (v != 0u && n > 0);
    put(ctx, &d[n]);
}

void stm32_board_pin_table(const stm32_board_def_t *def, void (*put)(void *ctx, const char *s),
                           void *ctx)
{
    static const char *const modes[] = {"input", "output", "alternate function", "analog"};
    put(ctx, "| pin | mode | AF | use |\n|---|---|---|---|\n");
    for (size_t i = 0; i < def->pin_count; i++) {
        const stm32_pin_t *p = &def->pins[i];
        char name[4] = {'P', (char)('A' + p->port), '\0', '\0'};
        put(ctx, "| ");
        put(ctx, name);
        put_u32(put, ctx, p->pin);
        put(ctx, " | ");
        put(ctx, modes[p->mode & 3u]);
        put(ctx, p->pull == STM32_GPIO_PULL_UP ? ", pull-up" : "");
        put(ctx, p->speed >= 2u ? ", fast | " : " | ");
        if (p->mode == STM32_GPIO_MODE_AF) {
            put(ctx, "AF");
            put_u32(put, ctx, p->af);
        } else {
            put(ctx, "-");
        }
        put(ctx, " | ");
        put(ctx, p->use);
        put(ctx, " |\n");
    }
}
