/* hd_excite: the identification's multisine (hd_excite.h). */
#include "hd_excite.h"

#include "hd_ctrl_trig.h"

const uint16_t hd_excite_bins[HD_EXCITE_LINES] = {
    2,   3,   4,   5,   6,   7,   8,   10,  11,  12,  14,  16,  18,  21,  24,
    27,  31,  35,  40,  45,  52,  59,  67,  76,  87,  99,  112, 128, 146, 166,
    189, 215, 245, 279, 318, 362, 413, 470, 535, 609, 694, 790, 900};

/* The rms of HD_EXCITE_LINES unit cosines on distinct bins of one period:
 * sqrt(n / 2) exactly (they are orthogonal over the period). */
#define RMS_OF_UNIT_LINES 4.63680924775f /* sqrt(43 / 2) */
_Static_assert(HD_EXCITE_LINES == 43u, "RMS_OF_UNIT_LINES is sqrt(HD_EXCITE_LINES / 2)");

/* Line k at tick t, in turns within [-0.5, 0.5): the bin's turns b t / P
 * reduced exactly in integers, minus the Schroeder phase k (k + 1) / (2 n)
 * turns reduced the same way, so float32 rounds only a number below one. */
static float line_turns(uint32_t k, uint32_t t)
{
    const uint32_t p = HD_EXCITE_PERIOD_TICKS;
    const uint32_t two_n = 2u * HD_EXCITE_LINES;
    const float at = (float)(((uint32_t)hd_excite_bins[k] * t) % p) / (float)p;
    const float phase = (float)((k * (k + 1u)) % two_n) / (float)two_n;
    float turns = at - phase; /* in (-1, 1) */
    if (turns >= 0.5f) {
        turns -= 1.0f;
    } else if (turns < -0.5f) {
        turns += 1.0f;
    }
    return turns;
}

static float sample(uint32_t t)
{
    float x = 0.0f;
    for (uint32_t k = 0; k < HD_EXCITE_LINES; k++) {
        float s;
        float c;
        sincos_quadrant(6.28318530718f * line_turns(k, t), &s, &c);
        x += c;
    }
    return x;
}

hd_ctrl_err_t hd_excite_build(hd_excite_t *e, float rms_a)
{
    if (e == 0) {
        return HD_CTRL_ERR_NULL;
    }
    if (!(rms_a >= HD_EXCITE_RMS_MIN_A && rms_a <= HD_EXCITE_RMS_MAX_A)) { /* NaN fails */
        return HD_CTRL_ERR_CONFIG;
    }
    /* Two passes (the peak, then the table) instead of a float buffer of a
     * period: 8 KB less of RAM for twice the slow work. */
    float peak = 0.0f;
    for (uint32_t t = 0; t < HD_EXCITE_PERIOD_TICKS; t++) {
        const float x = sample(t);
        const float a = x < 0.0f ? -x : x;
        peak = a > peak ? a : peak;
    }
    const float counts_per_unit = 32767.0f / peak;
    for (uint32_t t = 0; t < HD_EXCITE_PERIOD_TICKS; t++) {
        const float v = sample(t) * counts_per_unit;
        e->wave[t] = (int16_t)(v + (v >= 0.0f ? 0.5f : -0.5f));
    }
    e->rms_a = rms_a;
    e->peak_a = peak * rms_a / RMS_OF_UNIT_LINES;
    e->a_per_count = e->peak_a / 32767.0f;
    return HD_CTRL_OK;
}
