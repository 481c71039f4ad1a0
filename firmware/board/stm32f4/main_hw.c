/*
 * The joint firmware on an STM32F405/F446 board (hd_<board>.elf).
 *
 *   boot: reset cause + fault record, clock tree (8 MHz HSE -> 168 MHz, or
 *   the HSI fallback reported as HAL_RESET_CLOCK), watchdog, pins, tick
 *   timer, ADC, encoders, CAN, flash NVM -> hd_fw_init (which reads the
 *   boot info, loads the records and sets the CAN filter) -> tick on.
 *   tick (TIM1 update, 1 kHz): stm32_board_tick -> hd_fw_isr.
 *   main loop: hd_fw_background (commands, NVM), the watchdog reloaded only
 *   while the tick advances, then WFI.
 *
 * HD_BOARD_DEF names the board definition (stm32f4_boards.c).
 */
#include <stdint.h>

#include "hd_fw.h"
#include "stm32f4_board.h"
#include "stm32f4_startup.h"

#ifndef HD_BOARD_DEF
#error "HD_BOARD_DEF must name a stm32_board_def_t (stm32_board_odrive_v3, ...)"
#endif

static stm32_board_t g_board;
static hd_fw_t g_fw;
static hal_t g_hal;

void TIM1_UP_TIM10_IRQHandler(void);
void CAN1_TX_IRQHandler(void);

void TIM1_UP_TIM10_IRQHandler(void)
{
    stm32_board_tick(&g_board, &g_fw);
}

void CAN1_TX_IRQHandler(void)
{
    stm32_can_tx_service(&g_board.can);
}

_Noreturn void board_fault(const stm32_fault_record_t *rec)
{
    (void)rec; /* reported at the next boot */
    stm32_reboot();
    for (;;) {
    }
}

void board_early_init(void)
{
}

_Noreturn void board_exit(int status)
{
    (void)status;
    stm32_reboot();
    for (;;) {
    }
}

int main(void)
{
    stm32_periph_t p;
    stm32_periph_hw(&HD_BOARD_DEF, &p);
    (void)stm32_board_boot(&g_board, &HD_BOARD_DEF, &p, &g_stm32_fault_record, &g_hal);
    hd_fw_config_t cfg;
    hd_fw_config_default(&cfg);
    cfg.adc_volts_per_count = HD_BOARD_DEF.adc_volts_per_count; /* until a saved configuration */
    if (hd_fw_init(&g_fw, &g_hal, &cfg) != HD_FW_OK) {
        return 1; /* the defaults are checked at build time by the host tests */
    }
    stm32_board_start(&g_board);
    uint32_t fed = g_board.ticks;
    for (;;) {
        (void)hd_fw_background(&g_fw);
        if (g_board.ticks != fed) { /* the tick is alive: feed the watchdog */
            fed = g_board.ticks;
            stm32_iwdg_reload(g_board.p.iwdg);
        }
        __asm__ volatile("wfi" ::: "memory");
    }
}
