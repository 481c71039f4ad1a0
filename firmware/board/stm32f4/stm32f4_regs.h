/*
 * stm32f4_regs: the STM32F405/F446 registers this port uses, written from
 * the reference manuals (RM0090 for the F405, RM0390 for the F446; the
 * blocks used here are identical on both).  Register and bit names follow
 * the manuals: RCC_CR.HSERDY is STM32_RCC_CR_HSERDY, CAN_MCR.INRQ is
 * STM32_CAN_MCR_INRQ, and so on.  Only what the drivers touch is defined.
 *
 * Every driver reaches its peripheral through a pointer to one of these
 * blocks, handed in by the caller (the board passes the fixed addresses
 * below, the host tests pass a model's RAM block), and reads/writes it only
 * through STM32_RD / STM32_WR.  On the MCU those are plain volatile
 * accesses; a host test build defines STM32_REG_HOOKS and routes them to a
 * register-level model of the peripheral (tests/stm32f4/models).
 */
#ifndef STM32F4_REGS_H
#define STM32F4_REGS_H

#include <stdint.h>

#ifdef __cplusplus
extern "C" {
#endif

typedef volatile uint32_t stm32_reg_t;

#ifdef STM32_REG_HOOKS
uint32_t stm32_reg_read(const stm32_reg_t *reg);
void stm32_reg_write(stm32_reg_t *reg, uint32_t value);
/* Stores into memory-mapped flash (programming): bytes = 1 or 4. */
void stm32_mem_write(volatile uint8_t *addr, uint32_t value, unsigned bytes);
#define STM32_RD(reg) stm32_reg_read(&(reg))
#define STM32_WR(reg, value) stm32_reg_write(&(reg), (value))
#define STM32_MEM_WR32(addr, value) stm32_mem_write((addr), (value), 4u)
#define STM32_MEM_WR8(addr, value) stm32_mem_write((addr), (value), 1u)
#else
#define STM32_RD(reg) (reg)
#define STM32_WR(reg, value) ((reg) = (value))
#define STM32_MEM_WR32(addr, value) (*(volatile uint32_t *)(volatile void *)(addr) = (value))
#define STM32_MEM_WR8(addr, value) (*(addr) = (uint8_t)(value))
#endif
/* Read-modify-write: set and clear bits of a read/write register. */
#define STM32_SET(reg, bits) STM32_WR(reg, STM32_RD(reg) | (bits))
#define STM32_CLR(reg, bits) STM32_WR(reg, STM32_RD(reg) & ~(uint32_t)(bits))

/* The one way this port waits for hardware: poll until (reg & mask) ==
 * want, at most `polls` reads.  Returns 1 when the condition was seen, 0 on
 * timeout.  Every caller turns a timeout into an error code or fault bit. */
static inline int stm32_wait(const stm32_reg_t *reg, uint32_t mask, uint32_t want, uint32_t polls)
{
    for (uint32_t i = 0; i < polls; i++) {
#ifdef STM32_REG_HOOKS
        uint32_t v = stm32_reg_read(reg);
#else
        uint32_t v = *reg;
#endif
        if ((v & mask) == want) {
            return 1;
        }
    }
    return 0;
}

/* Short critical sections (PRIMASK) around state shared by the tick
 * interrupt, the CAN interrupt and the main loop.  No-ops on the host. */
static inline uint32_t stm32_irq_save(void)
{
#if defined(__arm__)
    uint32_t primask;
    __asm__ volatile("mrs %0, primask\n\tcpsid i" : "=r"(primask)::"memory");
    return primask;
#else
    return 0u;
#endif
}

static inline void stm32_irq_restore(uint32_t primask)
{
#if defined(__arm__)
    __asm__ volatile("msr primask, %0" ::"r"(primask) : "memory");
#else
    (void)primask;
#endif
}

/* ------------------------------------------------------------ memory map */
#define STM32_FLASH_MEM_BASE 0x08000000u
#define STM32_TIM2_BASE 0x40000000u
#define STM32_TIM3_BASE 0x40000400u
#define STM32_TIM4_BASE 0x40000800u
#define STM32_IWDG_BASE 0x40003000u
#define STM32_CAN1_BASE 0x40006400u
#define STM32_TIM1_BASE 0x40010000u
#define STM32_ADC1_BASE 0x40012000u
#define STM32_ADC_COMMON_BASE 0x40012300u
#define STM32_GPIOA_BASE 0x40020000u
#define STM32_GPIO_STRIDE 0x400u  /* GPIOB = GPIOA + 0x400, ... */
#define STM32_RCC_BASE 0x40023800u
#define STM32_FLASH_IF_BASE 0x40023C00u

/* ------------------------------------------------------------------- RCC */
typedef struct {
    stm32_reg_t CR;          /* 0x00 */
    stm32_reg_t PLLCFGR;     /* 0x04 */
    stm32_reg_t CFGR;        /* 0x08 */
    stm32_reg_t CIR;         /* 0x0C */
    stm32_reg_t AHB1RSTR;    /* 0x10 */
    stm32_reg_t AHB2RSTR;    /* 0x14 */
    stm32_reg_t AHB3RSTR;    /* 0x18 */
    stm32_reg_t reserved0;   /* 0x1C */
    stm32_reg_t APB1RSTR;    /* 0x20 */
    stm32_reg_t APB2RSTR;    /* 0x24 */
    stm32_reg_t reserved1[2];
    stm32_reg_t AHB1ENR;     /* 0x30 */
    stm32_reg_t AHB2ENR;     /* 0x34 */
    stm32_reg_t AHB3ENR;     /* 0x38 */
    stm32_reg_t reserved2;
    stm32_reg_t APB1ENR;     /* 0x40 */
    stm32_reg_t APB2ENR;     /* 0x44 */
    stm32_reg_t reserved3[2];
    stm32_reg_t AHB1LPENR;   /* 0x50 */
    stm32_reg_t AHB2LPENR;   /* 0x54 */
    stm32_reg_t AHB3LPENR;   /* 0x58 */
    stm32_reg_t reserved4;
    stm32_reg_t APB1LPENR;   /* 0x60 */
    stm32_reg_t APB2LPENR;   /* 0x64 */
    stm32_reg_t reserved5[2];
    stm32_reg_t BDCR;        /* 0x70 */
    stm32_reg_t CSR;         /* 0x74 */
} stm32_rcc_t;

#define STM32_RCC_CR_HSIRDY (1u << 1)
#define STM32_RCC_CR_HSEON (1u << 16)
#define STM32_RCC_CR_HSERDY (1u << 17)
#define STM32_RCC_CR_PLLON (1u << 24)
#define STM32_RCC_CR_PLLRDY (1u << 25)

#define STM32_RCC_PLLCFGR_PLLM_POS 0u   /* 6 bits, 2..63 */
#define STM32_RCC_PLLCFGR_PLLN_POS 6u   /* 9 bits, 50..432 */
#define STM32_RCC_PLLCFGR_PLLP_POS 16u  /* 2 bits: 0 = /2, 1 = /4, 2 = /6, 3 = /8 */
#define STM32_RCC_PLLCFGR_PLLSRC_HSE (1u << 22)
#define STM32_RCC_PLLCFGR_PLLQ_POS 24u  /* 4 bits, 2..15 */

#define STM32_RCC_CFGR_SW_MASK 0x3u
#define STM32_RCC_CFGR_SW_HSI 0x0u
#define STM32_RCC_CFGR_SW_HSE 0x1u
#define STM32_RCC_CFGR_SW_PLL 0x2u
#define STM32_RCC_CFGR_SWS_POS 2u
#define STM32_RCC_CFGR_PPRE1_POS 10u    /* 0xx: /1, 100: /2, 101: /4, 110: /8, 111: /16 */
#define STM32_RCC_CFGR_PPRE2_POS 13u
#define STM32_RCC_PPRE_DIV1 0x0u
#define STM32_RCC_PPRE_DIV2 0x4u
#define STM32_RCC_PPRE_DIV4 0x5u
#define STM32_RCC_PPRE_DIV8 0x6u
#define STM32_RCC_PPRE_DIV16 0x7u

#define STM32_RCC_AHB1ENR_GPIOAEN (1u << 0)  /* GPIOxEN = bit x - 'A' */
#define STM32_RCC_APB1ENR_TIM3EN (1u << 1)
#define STM32_RCC_APB1ENR_TIM4EN (1u << 2)
#define STM32_RCC_APB1ENR_CAN1EN (1u << 25)
#define STM32_RCC_APB2ENR_TIM1EN (1u << 0)
#define STM32_RCC_APB2ENR_ADC1EN (1u << 8)

#define STM32_RCC_CSR_LSION (1u << 0)
#define STM32_RCC_CSR_RMVF (1u << 24)
#define STM32_RCC_CSR_BORRSTF (1u << 25)
#define STM32_RCC_CSR_PINRSTF (1u << 26)
#define STM32_RCC_CSR_PORRSTF (1u << 27)
#define STM32_RCC_CSR_SFTRSTF (1u << 28)
#define STM32_RCC_CSR_IWDGRSTF (1u << 29)
#define STM32_RCC_CSR_WWDGRSTF (1u << 30)

/* --------------------------------------------------------- FLASH interface */
typedef struct {
    stm32_reg_t ACR;      /* 0x00 */
    stm32_reg_t KEYR;     /* 0x04 */
    stm32_reg_t OPTKEYR;  /* 0x08 */
    stm32_reg_t SR;       /* 0x0C */
    stm32_reg_t CR;       /* 0x10 */
    stm32_reg_t OPTCR;    /* 0x14 */
} stm32_flash_t;

#define STM32_FLASH_ACR_LATENCY_MASK 0xFu
#define STM32_FLASH_ACR_PRFTEN (1u << 8)
#define STM32_FLASH_ACR_ICEN (1u << 9)
#define STM32_FLASH_ACR_DCEN (1u << 10)
#define STM32_FLASH_ACR_DCRST (1u << 12)

#define STM32_FLASH_KEY1 0x45670123u
#define STM32_FLASH_KEY2 0xCDEF89ABu

#define STM32_FLASH_SR_EOP (1u << 0)
#define STM32_FLASH_SR_OPERR (1u << 1)
#define STM32_FLASH_SR_WRPERR (1u << 4)
#define STM32_FLASH_SR_PGAERR (1u << 5)
#define STM32_FLASH_SR_PGPERR (1u << 6)
#define STM32_FLASH_SR_PGSERR (1u << 7)
#define STM32_FLASH_SR_BSY (1u << 16)
#define STM32_FLASH_SR_ERRORS (STM32_FLASH_SR_OPERR | STM32_FLASH_SR_WRPERR | \
                               STM32_FLASH_SR_PGAERR | STM32_FLASH_SR_PGPERR | \
                               STM32_FLASH_SR_PGSERR)

#define STM32_FLASH_CR_PG (1u << 0)
#define STM32_FLASH_CR_SER (1u << 1)
#define STM32_FLASH_CR_SNB_POS 3u        /* 4 bits: sector number */
#define STM32_FLASH_CR_SNB_MASK (0xFu << 3)
#define STM32_FLASH_CR_PSIZE_POS 8u      /* 00: x8, 01: x16, 10: x32, 11: x64 */
#define STM32_FLASH_CR_PSIZE_MASK (0x3u << 8)
#define STM32_FLASH_CR_PSIZE_X8 (0x0u << 8)
#define STM32_FLASH_CR_PSIZE_X32 (0x2u << 8)
#define STM32_FLASH_CR_STRT (1u << 16)
#define STM32_FLASH_CR_LOCK (1u << 31)

/* ------------------------------------------------ timers (TIM1..TIM5, TIM8) */
/* One layout for the advanced (TIM1/TIM8) and general-purpose timers; RCR
 * and BDTR exist on TIM1/TIM8 only. */
typedef struct {
    stm32_reg_t CR1;    /* 0x00 */
    stm32_reg_t CR2;    /* 0x04 */
    stm32_reg_t SMCR;   /* 0x08 */
    stm32_reg_t DIER;   /* 0x0C */
    stm32_reg_t SR;     /* 0x10 */
    stm32_reg_t EGR;    /* 0x14 */
    stm32_reg_t CCMR1;  /* 0x18 */
    stm32_reg_t CCMR2;  /* 0x1C */
    stm32_reg_t CCER;   /* 0x20 */
    stm32_reg_t CNT;    /* 0x24 */
    stm32_reg_t PSC;    /* 0x28 */
    stm32_reg_t ARR;    /* 0x2C */
    stm32_reg_t RCR;    /* 0x30 */
    stm32_reg_t CCR1;   /* 0x34 */
    stm32_reg_t CCR2;   /* 0x38 */
    stm32_reg_t CCR3;   /* 0x3C */
    stm32_reg_t CCR4;   /* 0x40 */
    stm32_reg_t BDTR;   /* 0x44 */
    stm32_reg_t DCR;    /* 0x48 */
    stm32_reg_t DMAR;   /* 0x4C */
} stm32_tim_t;

#define STM32_TIM_CR1_CEN (1u << 0)
#define STM32_TIM_CR1_URS (1u << 2)   /* only over/underflow raises UIF */
#define STM32_TIM_CR1_ARPE (1u << 7)
#define STM32_TIM_CR2_MMS_MASK (0x7u << 4)
#define STM32_TIM_CR2_MMS_UPDATE (0x2u << 4)  /* TRGO = update event */
#define STM32_TIM_SMCR_SMS_MASK 0x7u
#define STM32_TIM_SMCR_SMS_ENCODER3 0x3u      /* count on TI1 and TI2 edges */
#define STM32_TIM_DIER_UIE (1u << 0)
#define STM32_TIM_SR_UIF (1u << 0)            /* rc_w0 */
#define STM32_TIM_EGR_UG (1u << 0)
#define STM32_TIM_CCMR1_CC1S_TI1 (0x1u << 0)
#define STM32_TIM_CCMR1_IC1F_POS 4u
#define STM32_TIM_CCMR1_CC2S_TI2 (0x1u << 8)
#define STM32_TIM_CCMR1_IC2F_POS 12u
#define STM32_TIM_CCER_CC1E (1u << 0)
#define STM32_TIM_CCER_CC1P (1u << 1)
#define STM32_TIM_CCER_CC2E (1u << 4)

/* ------------------------------------------------------------------- ADC */
typedef struct {
    stm32_reg_t SR;       /* 0x00 */
    stm32_reg_t CR1;      /* 0x04 */
    stm32_reg_t CR2;      /* 0x08 */
    stm32_reg_t SMPR1;    /* 0x0C: channels 10..18 */
    stm32_reg_t SMPR2;    /* 0x10: channels 0..9 */
    stm32_reg_t JOFR[4];  /* 0x14..0x20 */
    stm32_reg_t HTR;      /* 0x24 */
    stm32_reg_t LTR;      /* 0x28 */
    stm32_reg_t SQR1;     /* 0x2C */
    stm32_reg_t SQR2;     /* 0x30 */
    stm32_reg_t SQR3;     /* 0x34 */
    stm32_reg_t JSQR;     /* 0x38 */
    stm32_reg_t JDR[4];   /* 0x3C..0x48 */
    stm32_reg_t DR;       /* 0x4C */
} stm32_adc_t;

typedef struct {
    stm32_reg_t CSR;  /* 0x00 (ADC common base 0x40012300) */
    stm32_reg_t CCR;  /* 0x04 */
    stm32_reg_t CDR;  /* 0x08 */
} stm32_adc_common_t;

#define STM32_ADC_SR_JEOC (1u << 2)   /* rc_w0 */
#define STM32_ADC_SR_JSTRT (1u << 3)  /* rc_w0 */
#define STM32_ADC_CR2_ADON (1u << 0)
#define STM32_ADC_CR2_ALIGN (1u << 11)
#define STM32_ADC_CR2_JEXTSEL_POS 16u
#define STM32_ADC_CR2_JEXTSEL_MASK (0xFu << 16)
#define STM32_ADC_CR2_JEXTEN_MASK (0x3u << 20)
#define STM32_ADC_CR2_JEXTEN_RISING (0x1u << 20)
#define STM32_ADC_CR2_JSWSTART (1u << 22)
/* JEXTSEL codes (RM0090 ADC_CR2): the timer event that starts the injected
 * group. */
#define STM32_ADC_JEXTSEL_TIM1_TRGO 0x1u
#define STM32_ADC_JEXTSEL_TIM2_TRGO 0x3u
/* JSQR: with JL = 0 (one conversion) the ADC converts the channel in JSQ4
 * (bits 19:15) and stores the result in JDR1. */
#define STM32_ADC_JSQR_JSQ4_POS 15u
#define STM32_ADC_JSQR_JL_POS 20u
#define STM32_ADC_CCR_ADCPRE_POS 16u  /* 00: PCLK2/2, 01: /4, 10: /6, 11: /8 */
#define STM32_ADC_CCR_ADCPRE_MASK (0x3u << 16)
#define STM32_ADC_SMP_CODE_MAX 7u     /* 480 cycles */

/* ----------------------------------------------------------------- bxCAN */
typedef struct {
    stm32_reg_t TIR;   /* identifier, TXRQ */
    stm32_reg_t TDTR;  /* DLC */
    stm32_reg_t TDLR;  /* data bytes 0..3 */
    stm32_reg_t TDHR;  /* data bytes 4..7 */
} stm32_can_tx_mailbox_t;

typedef struct {
    stm32_reg_t RIR;
    stm32_reg_t RDTR;
    stm32_reg_t RDLR;
    stm32_reg_t RDHR;
} stm32_can_rx_fifo_t;

#define STM32_CAN_FILTER_BANKS 28u

typedef struct {
    stm32_reg_t MCR;                      /* 0x000 */
    stm32_reg_t MSR;                      /* 0x004 */
    stm32_reg_t TSR;                      /* 0x008 */
    stm32_reg_t RF0R;                     /* 0x00C */
    stm32_reg_t RF1R;                     /* 0x010 */
    stm32_reg_t IER;                      /* 0x014 */
    stm32_reg_t ESR;                      /* 0x018 */
    stm32_reg_t BTR;                      /* 0x01C */
    stm32_reg_t reserved0[88];            /* 0x020..0x17F */
    stm32_can_tx_mailbox_t TX[3];         /* 0x180 */
    stm32_can_rx_fifo_t RX[2];            /* 0x1B0 */
    stm32_reg_t reserved1[12];            /* 0x1D0..0x1FF */
    stm32_reg_t FMR;                      /* 0x200 */
    stm32_reg_t FM1R;                     /* 0x204 */
    stm32_reg_t reserved2;
    stm32_reg_t FS1R;                     /* 0x20C */
    stm32_reg_t reserved3;
    stm32_reg_t FFA1R;                    /* 0x214 */
    stm32_reg_t reserved4;
    stm32_reg_t FA1R;                     /* 0x21C */
    stm32_reg_t reserved5[8];             /* 0x220..0x23F */
    stm32_reg_t FR[STM32_CAN_FILTER_BANKS][2]; /* 0x240: FiR1, FiR2 */
} stm32_can_t;

#define STM32_CAN_MCR_INRQ (1u << 0)
#define STM32_CAN_MCR_SLEEP (1u << 1)
#define STM32_CAN_MCR_TXFP (1u << 2)    /* transmit in request order */
#define STM32_CAN_MCR_ABOM (1u << 6)    /* automatic bus-off management */
#define STM32_CAN_MCR_DBF (1u << 16)
#define STM32_CAN_MSR_INAK (1u << 0)
#define STM32_CAN_MSR_SLAK (1u << 1)
#define STM32_CAN_TSR_RQCP0 (1u << 0)   /* rc_w1; RQCPx = bit 8 x */
#define STM32_CAN_TSR_TXOK0 (1u << 1)
#define STM32_CAN_TSR_MAILBOX_SHIFT 8u
#define STM32_CAN_TSR_TME0 (1u << 26)   /* TMEx = bit 26 + x */
#define STM32_CAN_RFR_FMP_MASK 0x3u
#define STM32_CAN_RFR_FULL (1u << 3)    /* rc_w1 */
#define STM32_CAN_RFR_FOVR (1u << 4)    /* rc_w1 */
#define STM32_CAN_RFR_RFOM (1u << 5)    /* release the output mailbox */
#define STM32_CAN_IER_TMEIE (1u << 0)
#define STM32_CAN_ESR_EWGF (1u << 0)
#define STM32_CAN_ESR_EPVF (1u << 1)
#define STM32_CAN_ESR_BOFF (1u << 2)
#define STM32_CAN_ESR_LEC_POS 4u
#define STM32_CAN_ESR_LEC_MASK (0x7u << 4)
#define STM32_CAN_ESR_LEC_USER 0x7u     /* never set by hardware: "no new error" */
#define STM32_CAN_ESR_TEC_POS 16u
#define STM32_CAN_ESR_REC_POS 24u
#define STM32_CAN_BTR_BRP_MASK 0x3FFu
#define STM32_CAN_BTR_TS1_POS 16u       /* 4 bits: BS1 - 1 */
#define STM32_CAN_BTR_TS2_POS 20u       /* 3 bits: BS2 - 1 */
#define STM32_CAN_BTR_SJW_POS 24u       /* 2 bits: SJW - 1 */
#define STM32_CAN_BTR_LBKM (1u << 30)
#define STM32_CAN_BTR_SILM (1u << 31)
#define STM32_CAN_TIR_TXRQ (1u << 0)
#define STM32_CAN_IR_RTR (1u << 1)      /* TIxR / RIxR */
#define STM32_CAN_IR_IDE (1u << 2)
#define STM32_CAN_IR_EXID_POS 3u
#define STM32_CAN_IR_STID_POS 21u
#define STM32_CAN_DTR_DLC_MASK 0xFu
#define STM32_CAN_FMR_FINIT (1u << 0)

/* ------------------------------------------------------------------ IWDG */
typedef struct {
    stm32_reg_t KR;   /* 0x00 */
    stm32_reg_t PR;   /* 0x04 */
    stm32_reg_t RLR;  /* 0x08 */
    stm32_reg_t SR;   /* 0x0C */
} stm32_iwdg_t;

#define STM32_IWDG_KEY_ENABLE 0xCCCCu
#define STM32_IWDG_KEY_RELOAD 0xAAAAu
#define STM32_IWDG_KEY_ACCESS 0x5555u
#define STM32_IWDG_SR_PVU (1u << 0)
#define STM32_IWDG_SR_RVU (1u << 1)

/* ------------------------------------------------------------------ GPIO */
typedef struct {
    stm32_reg_t MODER;    /* 0x00: 2 bits per pin, 10 = alternate function, 11 = analog */
    stm32_reg_t OTYPER;   /* 0x04 */
    stm32_reg_t OSPEEDR;  /* 0x08 */
    stm32_reg_t PUPDR;    /* 0x0C: 01 = pull-up */
    stm32_reg_t IDR;      /* 0x10 */
    stm32_reg_t ODR;      /* 0x14 */
    stm32_reg_t BSRR;     /* 0x18 */
    stm32_reg_t LCKR;     /* 0x1C */
    stm32_reg_t AFR[2];   /* 0x20: AFRL (pins 0..7), AFRH (8..15), 4 bits per pin */
} stm32_gpio_t;

#define STM32_GPIO_MODE_AF 0x2u
#define STM32_GPIO_MODE_ANALOG 0x3u
#define STM32_GPIO_PULL_UP 0x1u

/* --------------------------------------------------- Cortex-M4 system (SCB) */
#define STM32_SCB_AIRCR (*(volatile uint32_t *)0xE000ED0Cu)
#define STM32_SCB_SHCSR (*(volatile uint32_t *)0xE000ED24u)
#define STM32_SCB_CFSR (*(volatile uint32_t *)0xE000ED28u)
#define STM32_SCB_HFSR (*(volatile uint32_t *)0xE000ED2Cu)
#define STM32_SCB_MMFAR (*(volatile uint32_t *)0xE000ED34u)
#define STM32_SCB_BFAR (*(volatile uint32_t *)0xE000ED38u)
#define STM32_SCB_CPACR (*(volatile uint32_t *)0xE000ED88u)
#define STM32_SCB_AIRCR_VECTKEY (0x05FAu << 16)
#define STM32_SCB_AIRCR_SYSRESETREQ (1u << 2)
#define STM32_SCB_SHCSR_FAULTS_ENA (7u << 16)  /* MemManage, BusFault, UsageFault */
#define STM32_SCB_CFSR_MMARVALID (1u << 7)
#define STM32_SCB_CFSR_BFARVALID (1u << 15)
/* Data watchpoint and trace unit: the free-running cycle counter. */
#define STM32_DEMCR (*(volatile uint32_t *)0xE000EDFCu)
#define STM32_DEMCR_TRCENA (1u << 24)
#define STM32_DWT_CTRL (*(volatile uint32_t *)0xE0001000u)
#define STM32_DWT_CTRL_CYCCNTENA (1u << 0)
#define STM32_DWT_CYCCNT (*(volatile uint32_t *)0xE0001004u)
#define STM32_NVIC_ISER ((volatile uint32_t *)0xE000E100u)
#define STM32_NVIC_ICER ((volatile uint32_t *)0xE000E180u)
#define STM32_NVIC_IPR ((volatile uint8_t *)0xE000E400u)

/* Interrupt numbers (vector = 16 + n) used by this port; the same on the
 * F405 and the F446. */
#define STM32_IRQ_CAN1_TX 19u
#define STM32_IRQ_TIM1_UP_TIM10 25u
#define STM32_IRQ_TIM2 28u
#define STM32_IRQ_COUNT 97u  /* F446: 97 vectors after the 16 system ones (F405: 82) */

#ifdef __cplusplus
}
#endif

#endif /* STM32F4_REGS_H */
