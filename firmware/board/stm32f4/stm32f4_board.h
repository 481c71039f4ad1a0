/*
 * stm32f4_board: the drivers put together as the firmware's hal_t on an
 * STM32F405/F446 joint board.
 *
 * A board is described by data (stm32_board_def_t, one per supported
 * board in stm32f4_boards.c: its pins, which timer ticks, which ADC channel
 * carries the bridge, which timers count the encoders, the CAN bit rate)
 * and reaches its peripherals through an stm32_periph_t: the fixed
 * addresses on the MCU (stm32_periph_hw), RAM blocks in the instruction
 * count bench.  stm32_board_boot brings everything up in order and fills
 * the hal_t; stm32_board_tick is the body of the tick interrupt.
 */
#ifndef STM32F4_BOARD_H
#define STM32F4_BOARD_H

#include <stdbool.h>
#include <stddef.h>
#include <stdint.h>

#include "hal.h"
#include "hd_fw.h"
#include "stm32f4_adc.h"
#include "stm32f4_can.h"
#include "stm32f4_clock.h"
#include "stm32f4_flash.h"
#include "stm32f4_gpio.h"
#include "stm32f4_regs.h"
#include "stm32f4_system.h"
#include "stm32f4_tim.h"

#ifdef __cplusplus
extern "C" {
#endif

#define STM32_BOARD_TICK_HZ 1000u
#define STM32_BOARD_SYSCLK_HZ 168000000u
/* Bounded waits, as poll counts (one poll is at least one peripheral read,
 * two or more core cycles at 168 MHz, so each bound is at least the time
 * given; at 16 MHz on the fallback clock they last ten times longer). */
#define STM32_BOARD_READY_POLLS 200000u   /* clock ready flags: >= 2.4 ms, HSE start-up typ. 2 ms */
#define STM32_BOARD_CAN_POLLS 200000u     /* INAK/SLAK: >= 11 bits at 125 kbit/s */
#define STM32_BOARD_ADC_POLLS 1000u       /* JEOC: >= 12 us, a conversion takes 3.2 us */
#define STM32_BOARD_ERASE_POLLS 100000000u/* one 16 KB sector: >= 1.2 s, datasheet max 0.5 s */
#define STM32_BOARD_PROGRAM_POLLS 20000u  /* one word: >= 240 us, datasheet max 100 us */
/* IWDG: LSI / 32, reload 1499: 1.0 s at the fastest LSI (47 kHz), 2.8 s at
 * the slowest (17 kHz); longer than a sector erase, which stalls the CPU. */
#define STM32_BOARD_IWDG_PR 3u
#define STM32_BOARD_IWDG_RELOAD 1499u

/* Where a board's peripherals are. */
typedef struct {
    stm32_rcc_t *rcc;
    stm32_flash_t *flash;
    stm32_iwdg_t *iwdg;
    stm32_gpio_t *gpio[STM32_GPIO_PORTS];
    stm32_tim_t *tick;
    stm32_adc_t *adc;
    stm32_adc_common_t *adc_common;
    stm32_tim_t *motor_enc;
    stm32_tim_t *output_enc;     /* NULL: no output encoder */
    stm32_can_t *can;
    uint8_t *nvm_mem;            /* memory-mapped start of the NVM sectors */
} stm32_periph_t;

typedef struct {
    const char *name;            /* "odrive-v3" ... */
    const char *mcu;             /* "STM32F405RG" ... */
    uint32_t board_id;           /* hal_system_t.board_id: four characters */
    uint32_t hse_hz;
    uint32_t can_bitrate;
    const stm32_pin_t *pins;
    size_t pin_count;
    uintptr_t tick_base;         /* timer register blocks (fixed addresses) */
    bool tick_on_apb2;           /* TIM1/TIM8: APB2 timer clock, else APB1 */
    uint32_t tick_irq;
    uintptr_t motor_enc_base;
    uint8_t motor_enc_bits;      /* 16 or 32 */
    uintptr_t output_enc_base;   /* 0: none */
    uint8_t output_enc_bits;
    uint8_t adc_channel;         /* ADC1 injected channel of the bridge amplifier */
    float adc_volts_per_count;   /* at the ADC pin: VREF+ / 4096 (the amplifier gain
                                  * belongs to the calibration) */
    uint8_t adc_jextsel;         /* the tick timer's TRGO */
    uint32_t apb1_enr, apb2_enr; /* peripheral clocks to switch on */
    uint32_t nvm_first_sector;
    uint32_t nvm_sectors;
    uint32_t nvm_sector_bytes;
} stm32_board_def_t;

extern const stm32_board_def_t stm32_board_odrive_v3;
extern const stm32_board_def_t stm32_board_mini_cheetah;

/* Extends the 32-bit DWT cycle counter to microseconds since boot with
 * 32-bit divisions only (a 64-bit division is a library call of a few
 * hundred cycles on the M4, and this runs every tick). */
typedef struct {
    uint32_t last;          /* counter at the previous call */
    uint32_t rem_cycles;    /* cycles not yet a whole microsecond */
    uint64_t us;            /* whole microseconds since start */
    uint32_t cycles_per_us; /* >= 1 */
} stm32_cycle_clock_t;

/* Takes the counter's value now; calls must come less than
 * 2^32 - cycles_per_us cycles apart (25 s at 168 MHz; the firmware calls
 * it every tick).  Returns the microseconds since start, rounded down:
 * floor(cycles since start / cycles_per_us). */
uint64_t stm32_cycle_clock_advance(stm32_cycle_clock_t *c, uint32_t now);

typedef struct {
    const stm32_board_def_t *def;
    stm32_periph_t p;
    stm32_clock_t clock;
    hal_boot_info_t boot;
    uint32_t init_errors;        /* STM32_BOARD_INIT_* that failed */
    stm32_adc_drv_t adc;
    stm32_encoder_t motor_enc, output_enc;
    stm32_can_drv_t can;
    stm32_flash_drv_t flash;
    stm32_cycle_clock_t cycles;
    volatile uint32_t ticks;
} stm32_board_t;

#define STM32_BOARD_INIT_PINS 0x1u
#define STM32_BOARD_INIT_TICK 0x2u
#define STM32_BOARD_INIT_ADC 0x4u
#define STM32_BOARD_INIT_CAN 0x8u
#define STM32_BOARD_INIT_IWDG 0x10u

/* The fixed peripheral addresses of a board definition. */
void stm32_periph_hw(const stm32_board_def_t *def, stm32_periph_t *out);

/* Reset cause and fault record (taken from *fault_rec), clock tree,
 * watchdog, pins, peripheral clocks, tick timer (stopped), ADC, encoders,
 * CAN (no filter: the firmware sets it), flash NVM; fills hal.  Failures
 * are recorded in b->init_errors; a part whose driver failed stays usable
 * (its calls return errors the firmware flags).  Returns init_errors. */
uint32_t stm32_board_boot(stm32_board_t *b, const stm32_board_def_t *def,
                          const stm32_periph_t *p, stm32_fault_record_t *fault_rec, hal_t *hal);

/* Points hal's parts at the board's drivers (part of stm32_board_boot;
 * the instruction-count bench calls it on drivers it set up itself). */
void stm32_board_bind(stm32_board_t *b, hal_t *hal);

/* Starts the tick timer and enables its interrupt and CAN's. */
void stm32_board_start(stm32_board_t *b);

/* The tick interrupt: acknowledges the timer, services CAN, runs hd_fw_isr. */
void stm32_board_tick(stm32_board_t *b, hd_fw_t *fw);

/* hal_t functions (ctx = the board). */
int stm32_board_encoder_read(void *ctx, hal_encoder_sample_t *out);
uint64_t stm32_board_time_us(void *ctx);
void stm32_board_boot_info(void *ctx, hal_boot_info_t *out);
void stm32_board_reboot(void *ctx);

/* Writes the board's pin/peripheral table as markdown (docs/how-to/stm32f4.md is
 * checked against it): calls put(ctx, text) piece by piece. */
void stm32_board_pin_table(const stm32_board_def_t *def, void (*put)(void *ctx, const char *s),
                           void *ctx);

#ifdef __cplusplus
}
#endif

#endif /* STM32F4_BOARD_H */
