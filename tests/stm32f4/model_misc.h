/*
 * model_misc: register-level models of the smaller STM32F4 blocks the
 * drivers use, written from RM0090:
 *  - ram_model: a block with no behaviour (GPIO, ADC common): plain storage.
 *  - tim_model: timer time base (PSC preloaded until an update event, ARR
 *    preloaded with ARPE, UIF set by overflow and by UG unless URS, SR
 *    cleared by writing 0, TRGO on update when CR2.MMS = 010) advanced by
 *    timer-kernel clocks; encoder mode 3 moves CNT modulo ARR + 1.
 *  - adc_model: injected group started by its JEXTSEL trigger (rising edge
 *    enabled) or JSWSTART, converting the JSQ channels (with JL = 0 only
 *    JSQ4) after `conv_reads` reads of SR, JDRx = input - JOFRx sign
 *    extended, JEOC/JSTRT cleared by writing 0.
 *  - rcc_model: HSE ready after `ready_reads` reads when a crystal is
 *    present, PLL lock only from a ready source with valid M/N/P, the
 *    system clock switch only to a ready source, checking on the switch
 *    that the flash wait states and bus prescalers suit the new clock;
 *    `absent` makes every register read 0 and ignore writes (QEMU).
 *  - iwdg_model: key register, PR/RLR writable only after 0x5555, PVU/RVU
 *    busy after a write.
 */
#ifndef MODEL_MISC_H
#define MODEL_MISC_H

#include <stdbool.h>
#include <stdint.h>

#include "reg_model.h"

#define STM32_HSI_HZ_MODEL 16000000u

typedef struct {
    reg_model_t rm;
} ram_model_t;

/* Serves `size` bytes at `block` as plain storage. */
void ram_model_init(ram_model_t *m, const char *name, volatile void *block, size_t size);

typedef void (*trgo_fn)(void *ctx, uint32_t source);

typedef struct {
    reg_model_t rm;
    stm32_tim_t regs;
    uint32_t psc_active, arr_active;
    uint64_t prescale_count;
    uint32_t updates;           /* update events (overflows and UG) */
    uint32_t trgo_source;       /* JEXTSEL code of this timer's TRGO */
    trgo_fn trgo;
    void *trgo_ctx;
} tim_model_t;

void tim_model_init(tim_model_t *m, const char *name);
/* Advances the running counter by n timer-kernel clocks. */
void tim_model_clock(tim_model_t *m, uint64_t n);
/* Encoder mode: moves the count by delta edges (sign = direction). */
void tim_model_encoder_move(tim_model_t *m, int64_t delta);

typedef struct {
    reg_model_t rm;
    stm32_adc_t regs;
    uint32_t input[19];         /* raw 12-bit conversion result per channel */
    uint32_t conv_reads;        /* SR reads until JEOC */
    uint32_t conv_left;
    bool converting;
    bool never_completes;       /* inject: JEOC never set */
    uint32_t conversions;
    uint32_t triggers_ignored;  /* triggers from other sources or with JEXTEN off */
} adc_model_t;

void adc_model_init(adc_model_t *m);
/* A timer's TRGO (trgo_fn): starts the injected group if selected. */
void adc_model_trigger(void *ctx, uint32_t source);

typedef struct {
    reg_model_t rm;
    stm32_rcc_t regs;
    bool absent;                /* no RCC model at all: reads 0 (QEMU) */
    bool hse_present;
    bool pll_locks;
    uint32_t ready_reads;
    uint32_t hse_left, pll_left, sw_left;
    uint32_t sw_target;
    const stm32_flash_t *flash; /* its ACR is checked on the switch to the PLL */
    uint32_t hse_hz;
    uint32_t violations;
    const char *last_violation;
} rcc_model_t;

void rcc_model_init(rcc_model_t *m, const stm32_flash_t *flash, uint32_t hse_hz);
/* SYSCLK the model is running on now. */
uint32_t rcc_model_sysclk(const rcc_model_t *m);

typedef struct {
    reg_model_t rm;
    stm32_iwdg_t regs;
    bool access;
    bool started;
    uint32_t reloads;
    uint32_t busy_reads;
    uint32_t busy_left;
    uint32_t violations;
} iwdg_model_t;

void iwdg_model_init(iwdg_model_t *m);

#endif /* MODEL_MISC_H */
