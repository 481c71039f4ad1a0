/* hd_can_gen_internal.h: the byte helpers of hd_can_gen.c and hd_can_gen_cmd.c.
 * Generated from firmware/hd_protocol.def by `cd tools && ../.venv/bin/python -m hdtools.protocol --write`: do not edit. */
#ifndef HD_CAN_GEN_INTERNAL_H
#define HD_CAN_GEN_INTERNAL_H

#include <stdint.h>
#include <string.h>

static inline uint32_t f32_bits(float v) { uint32_t u; memcpy(&u, &v, sizeof u); return u; }
static inline float bits_f32(uint32_t u) { float v; memcpy(&v, &u, sizeof v); return v; }
static inline int32_t sext(uint32_t raw, unsigned bits)
{
    const uint32_t sign = 1u << (bits - 1u);
    return (int32_t)(raw ^ sign) - (int32_t)sign;
}
/* Two 32-bit halves with constant shifts: a loop over a 64-bit
 * variable shift costs the Cortex-M4 a libgcc-style sequence per byte. */
static inline uint32_t load_u32(const uint8_t *d)
{
    return (uint32_t)d[0] | (uint32_t)d[1] << 8 | (uint32_t)d[2] << 16 | (uint32_t)d[3] << 24;
}
static inline uint64_t load_word(const uint8_t *d)
{
    return (uint64_t)load_u32(d) | (uint64_t)load_u32(d + 4) << 32;
}
static inline void store_u32(uint8_t *d, uint32_t u)
{
    d[0] = (uint8_t)u;
    d[1] = (uint8_t)(u >> 8);
    d[2] = (uint8_t)(u >> 16);
    d[3] = (uint8_t)(u >> 24);
}
static inline void store_word(uint8_t *d, uint64_t w)
{
    store_u32(d, (uint32_t)w);
    store_u32(d + 4, (uint32_t)(w >> 32));
}

#endif /* HD_CAN_GEN_INTERNAL_H */
