/* One capacity's sizes; built once per HD_KF_MAX_BLOCKS (see bench_memory.h). */
#include "bench_memory.h"
#include "dense_kf_f32.h"
#include "hd_pipeline.h"

#ifndef BENCH_MEM_CAP
#error "compile with -DBENCH_MEM_CAP=k -DHD_KF_MAX_BLOCKS=k"
#endif

#define BENCH_MEM_FN2(k) bench_mem_sizes_##k
#define BENCH_MEM_FN(k) BENCH_MEM_FN2(k)

void BENCH_MEM_FN(BENCH_MEM_CAP)(bench_mem_sizes_t *m)
{
    m->capacity_blocks = HD_KF_MAX_BLOCKS;
    m->capacity_states = HD_KF_MAX_STATES;
    m->hd_kf_bytes = sizeof(hd_kf_t);
    m->pipeline_bytes = sizeof(hd_pipeline_t);
    m->dense_f32_bytes = sizeof(dense_kf_f32_t);
    m->dense_f32_stack_bytes = 2u * sizeof(float) * DENSE_KF_MAX_N * DENSE_KF_MAX_N;
}
