/* reg_model: see reg_model.h. */
#include "reg_model.h"

#include <stdio.h>

#define MAX_MODELS 16u

static reg_model_t *g_models[MAX_MODELS];
static size_t g_count;
static uint32_t g_stray;

void reg_model_add(reg_model_t *m)
{
    if (g_count < MAX_MODELS) {
        m->reads = 0u;
        m->writes = 0u;
        g_models[g_count++] = m;
    }
}

void reg_model_reset(void)
{
    g_count = 0u;
    g_stray = 0u;
}

uint32_t reg_model_stray_accesses(void)
{
    return g_stray;
}

static reg_model_t *owner(const volatile void *addr, size_t *offset)
{
    const volatile uint8_t *a = addr;
    for (size_t i = 0; i < g_count; i++) {
        const volatile uint8_t *b = g_models[i]->base;
        if (a >= b && a < b + g_models[i]->size) {
            *offset = (size_t)(a - b);
            return g_models[i];
        }
    }
    return NULL;
}

uint32_t stm32_reg_read(const stm32_reg_t *reg)
{
    size_t off;
    reg_model_t *m = owner(reg, &off);
    if (m == NULL) {
        g_stray++;
        return *reg;
    }
    m->reads++;
    return m->read(m, off);
}

void stm32_reg_write(stm32_reg_t *reg, uint32_t value)
{
    size_t off;
    reg_model_t *m = owner(reg, &off);
    if (m == NULL) {
        g_stray++;
        *reg = value;
        return;
    }
    m->writes++;
    m->write(m, off, value);
}

void stm32_mem_write(volatile uint8_t *addr, uint32_t value, unsigned bytes)
{
    for (size_t i = 0; i < g_count; i++) {
        reg_model_t *m = g_models[i];
        if (m->mem != NULL && addr >= m->mem && addr < m->mem + m->mem_size) {
            m->mem_write(m, (size_t)(addr - m->mem), value, bytes);
            return;
        }
    }
    g_stray++;
}
