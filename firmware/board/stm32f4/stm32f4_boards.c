/*
 * stm32f4_boards: the supported boards as data.  docs/how-to/stm32f4.md's pin
 * tables are checked against these (tests/stm32f4/test_stm32_board.c).
 *
 * ODrive v3.x (STM32F405RG): pins as the ODrive v3.5/v3.6 firmware assigns
 * them (Firmware/Board/v3/board.cpp): CAN on PB8/PB9, the M0 encoder port
 * on TIM3 (PB4/PB5), the M1 encoder port on TIM4 (PB6/PB7) for the output
 * encoder, and GPIO4 (PA3 = ADC123_IN3) for the bridge amplifier.  This
 * image does not drive the motor stage: TIM1 only ticks (no outputs,
 * MOE = 0) and no gate-driver pin is configured.
 *
 * Mini Cheetah class (STM32F446RE): CAN on PB8/PB9 as on the Mini Cheetah
 * motor controller.  That board reads its motor angle from an SPI
 * magnetic encoder, which this port does not drive; the image expects a
 * quadrature A/B pair on TIM3 (PB4/PB5) and the bridge amplifier on PC4
 * (ADC12_IN14), pins its published firmware leaves unused.
 */
#include "stm32f4_board.h"

#define BOARD_ID(a, b, c, d) \
    ((uint32_t)(a) | ((uint32_t)(b) << 8) | ((uint32_t)(c) << 16) | ((uint32_t)(d) << 24))
#define PORT_A 0u
#define PORT_B 1u
#define PORT_C 2u
#define AF_TIM3_4_5 2u
#define AF_CAN1 9u
#define SPEED_FAST 2u /* OSPEEDR "fast": clean CAN edges at 1 Mbit/s */
#define NVM_SECTOR_BYTES 16384u  /* sectors 1 and 2: 16 KB each on F405 and F446 */
#define ADC_VREF_V 3.3f          /* VREF+ = VDDA = 3.3 V on both boards */

static const stm32_pin_t odrive_pins[] = {
    {PORT_B, 8, STM32_GPIO_MODE_AF, AF_CAN1, STM32_GPIO_PULL_UP, 0, "CAN1_RX (ODrive CAN_R)"},
    {PORT_B, 9, STM32_GPIO_MODE_AF, AF_CAN1, 0, SPEED_FAST, "CAN1_TX (ODrive CAN_D)"},
    {PORT_B, 4, STM32_GPIO_MODE_AF, AF_TIM3_4_5, 0, 0, "TIM3_CH1: motor encoder A (ODrive ENC0 A)"},
    {PORT_B, 5, STM32_GPIO_MODE_AF, AF_TIM3_4_5, 0, 0, "TIM3_CH2: motor encoder B (ODrive ENC0 B)"},
    {PORT_B, 6, STM32_GPIO_MODE_AF, AF_TIM3_4_5, 0, 0, "TIM4_CH1: output encoder A (ODrive ENC1 A)"},
    {PORT_B, 7, STM32_GPIO_MODE_AF, AF_TIM3_4_5, 0, 0, "TIM4_CH2: output encoder B (ODrive ENC1 B)"},
    {PORT_A, 3, STM32_GPIO_MODE_ANALOG, 0, 0, 0, "ADC1_IN3: bridge amplifier output (ODrive GPIO4)"},
};

const stm32_board_def_t stm32_board_odrive_v3 = {
    .name = "odrive-v3",
    .mcu = "STM32F405RG",
    .board_id = BOARD_ID('F', '4', '0', '5'),
    .hse_hz = 8000000u,
    .can_bitrate = 1000000u,
    .pins = odrive_pins,
    .pin_count = sizeof odrive_pins / sizeof odrive_pins[0],
    .tick_base = STM32_TIM1_BASE,
    .tick_on_apb2 = true,
    .tick_irq = STM32_IRQ_TIM1_UP_TIM10,
    .motor_enc_base = STM32_TIM3_BASE,
    .motor_enc_bits = 16u,
    .output_enc_base = STM32_TIM4_BASE,
    .output_enc_bits = 16u,
    .adc_channel = 3u,
    .adc_volts_per_count = ADC_VREF_V / 4096.0f,
    .adc_jextsel = STM32_ADC_JEXTSEL_TIM1_TRGO,
    .apb1_enr = STM32_RCC_APB1ENR_TIM3EN | STM32_RCC_APB1ENR_TIM4EN | STM32_RCC_APB1ENR_CAN1EN,
    .apb2_enr = STM32_RCC_APB2ENR_TIM1EN | STM32_RCC_APB2ENR_ADC1EN,
    .nvm_first_sector = 1u,
    .nvm_sectors = 2u,
    .nvm_sector_bytes = NVM_SECTOR_BYTES,
};

static const stm32_pin_t cheetah_pins[] = {
    {PORT_B, 8, STM32_GPIO_MODE_AF, AF_CAN1, STM32_GPIO_PULL_UP, 0, "CAN1_RX"},
    {PORT_B, 9, STM32_GPIO_MODE_AF, AF_CAN1, 0, SPEED_FAST, "CAN1_TX"},
    {PORT_B, 4, STM32_GPIO_MODE_AF, AF_TIM3_4_5, 0, 0, "TIM3_CH1: motor encoder A (quadrature)"},
    {PORT_B, 5, STM32_GPIO_MODE_AF, AF_TIM3_4_5, 0, 0, "TIM3_CH2: motor encoder B (quadrature)"},
    {PORT_C, 4, STM32_GPIO_MODE_ANALOG, 0, 0, 0, "ADC1_IN14: bridge amplifier output"},
};

const stm32_board_def_t stm32_board_mini_cheetah = {
    .name = "mini-cheetah",
    .mcu = "STM32F446RE",
    .board_id = BOARD_ID('F', '4', '4', '6'),
    .hse_hz = 8000000u,
    .can_bitrate = 1000000u,
    .pins = cheetah_pins,
    .pin_count = sizeof cheetah_pins / sizeof cheetah_pins[0],
    .tick_base = STM32_TIM1_BASE,
    .tick_on_apb2 = true,
    .tick_irq = STM32_IRQ_TIM1_UP_TIM10,
    .motor_enc_base = STM32_TIM3_BASE,
    .motor_enc_bits = 16u,
    .output_enc_base = 0u,
    .output_enc_bits = 0u,
    .adc_channel = 14u,
    .adc_volts_per_count = ADC_VREF_V / 4096.0f,
    .adc_jextsel = STM32_ADC_JEXTSEL_TIM1_TRGO,
    .apb1_enr = STM32_RCC_APB1ENR_TIM3EN | STM32_RCC_APB1ENR_CAN1EN,
    .apb2_enr = STM32_RCC_APB2ENR_TIM1EN | STM32_RCC_APB2ENR_ADC1EN,
    .nvm_first_sector = 1u,
    .nvm_sectors = 2u,
    .nvm_sector_bytes = NVM_SECTOR_BYTES,
};
