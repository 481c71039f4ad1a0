/*
 * Sizes of the filter state at several compile-time capacities.  Each
 * capacity is a separate translation unit (bench_memory_tu.c compiled with
 * -DHD_KF_MAX_BLOCKS=k), so sizeof is what the compiler lays out for a
 * firmware built with exactly that capacity.  Keep BENCH_MEM_CAPS in step
 * with HD_BENCH_MEM_CAPS in CMakeLists.txt.
 */
#ifndef BENCH_MEMORY_H
#define BENCH_MEMORY_H

#include <stddef.h>

typedef struct {
    int capacity_blocks;    /* HD_KF_MAX_BLOCKS of that translation unit */
    int capacity_states;    /* 2 * blocks + 1 (offset slot) */
    size_t hd_kf_bytes;     /* sizeof(hd_kf_t): the filter (state, P, config) */
    size_t pipeline_bytes;  /* sizeof(hd_pipeline_t): filter + tracker + T_exp */
    size_t dense_f32_bytes; /* sizeof(dense_kf_f32_t) */
    size_t dense_f32_stack_bytes; /* dense step's two n x n work matrices (its model,
                                     Phi and three vectors, is static) */
} bench_mem_sizes_t;

#define BENCH_MEM_CAPS(X) X(2) X(3) X(4) X(8)

#define BENCH_MEM_DECLARE(k) void bench_mem_sizes_##k(bench_mem_sizes_t *m);
BENCH_MEM_CAPS(BENCH_MEM_DECLARE)
#undef BENCH_MEM_DECLARE

#endif /* BENCH_MEMORY_H */
