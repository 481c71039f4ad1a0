/*
 * hd_excite: the excitation of the torque loop's identification, a periodic
 * multisine current added at the plant input (the drive's command) so that
 * a host can break the loop there: with x = command + excitation the
 * current the drive receives, L(jw) = -CMD(jw) / X(jw) and the plant the
 * law sees P(jw) = FB(jw) / X(jw), at the excited lines
 * (docs/how-to/tune-torque-loop.md; the host's side: tools/hdtools/torque_loop.py).
 *
 * The waveform is the control benchmark's (tools/hdtools/torque_loop.py,
 * multisine()): one period of HD_EXCITE_PERIOD_TICKS ticks, cosines on the
 * HD_EXCITE_LINES FFT bins of hd_excite_bins (1 to 450 Hz, log-spaced, at
 * 1 kHz), Schroeder phases -pi k (k + 1) / HD_EXCITE_LINES, scaled to the
 * rms asked for.  tests/device/test_identify.py checks the waveform the
 * firmware streams against that function.
 *
 * Pure: no I/O, no heap, no libm; float32.  hd_excite_build is slow work
 * (2 x HD_EXCITE_PERIOD_TICKS x HD_EXCITE_LINES sines and cosines): the
 * background, never the tick.
 * hd_excite_at is one table read and one multiply: the tick.
 */
#ifndef HD_EXCITE_H
#define HD_EXCITE_H

#include <stdint.h>

#include "hd_ctrl.h"

#ifdef __cplusplus
extern "C" {
#endif

#define HD_EXCITE_PERIOD_TICKS 2000u  /* 2 s at 1 kHz: lines on a 0.5 Hz grid */
#define HD_EXCITE_LINES 43u           /* 48 log-spaced 1..450 Hz, rounded to the grid, unique */
#define HD_EXCITE_RMS_MIN_A 1.0e-3f   /* IdentRms' range (firmware/hd_protocol.def) */
#define HD_EXCITE_RMS_MAX_A 100.0f

/* The excited bins (cycles per period), ascending. */
extern const uint16_t hd_excite_bins[HD_EXCITE_LINES];

typedef struct {
    int16_t wave[HD_EXCITE_PERIOD_TICKS]; /* one period, +-32767 = +-peak_a */
    float a_per_count;                    /* current per count of wave */
    float peak_a;                         /* the largest |current| of a period */
    float rms_a;                          /* the rms asked for */
} hd_excite_t;

/* Builds the waveform at rms_a (HD_EXCITE_RMS_MIN_A .. HD_EXCITE_RMS_MAX_A): HD_CTRL_OK,
 * HD_CTRL_ERR_NULL, or HD_CTRL_ERR_CONFIG (rms_a not finite or out of range;
 * *e is left as it was). */
hd_ctrl_err_t hd_excite_build(hd_excite_t *e, float rms_a);

/* The excitation at tick k of a run (periodic in HD_EXCITE_PERIOD_TICKS). */
static inline float hd_excite_at(const hd_excite_t *e, uint32_t k)
{
    return (float)e->wave[k % HD_EXCITE_PERIOD_TICKS] * e->a_per_count;
}

#ifdef __cplusplus
}
#endif

#endif /* HD_EXCITE_H */
