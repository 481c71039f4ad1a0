/*
 * hd_mark: instruction-count markers shared by the board ports (QEMU
 * mps2-an386, STM32F4 / netduinoplus2).  tools/target counts the
 * instructions between them with its QEMU plugin (tools/qemu-plugin).
 */
#ifndef HD_MARK_H
#define HD_MARK_H

#include <stdint.h>

#ifdef __cplusplus
extern "C" {
#endif

/* Instruction-count markers for the QEMU plugin (tools/qemu-plugin): three
 * distinct one-instruction functions (`bx lr`, in assembly so no compiler
 * merges them).  The plugin counts the instructions executed between a
 * call to hd_mark_begin and the next call to hd_mark_end; hd_mark_section
 * closes a group of intervals.  On hardware they cost a call and a return. */
void hd_mark_begin(void);
void hd_mark_end(void);
void hd_mark_section(void);

/* A loop of known length for checking the instruction counter: for n >= 1
 * it executes exactly 2 n + 1 instructions (n x `subs; bne`, then `bx lr`). */
void hd_bench_loop(uint32_t n);

/* The two sections every bench image starts with: "empty:-" (16 intervals
 * with nothing between the markers: the marker overhead) and "loop:-"
 * (hd_bench_loop(10), then hd_bench_loop(1010): the closed-form check).
 * section(label) prints the label line before each group. */
void hd_mark_calibration(void (*section)(const char *label));

#ifdef __cplusplus
}
#endif

#endif /* HD_MARK_H */
