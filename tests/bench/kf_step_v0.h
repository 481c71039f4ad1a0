/*
 * kf_step_v0: the filter step before issue 16, kept only as the compute
 * benchmark's baseline (see kf_step_v0.c).  Same model and configuration
 * as hd_kf (hd_kf_config_t, hd_kf_input_t); its own state and output types.
 */
#ifndef KF_STEP_V0_H
#define KF_STEP_V0_H

#include "hd_kf.h"

typedef struct {
    float torque_filtered_nm;
    float ripple_nm;
    float offset_nm;
    float innovation_nm;
    float innovation_var_nm2;
    float amplitude_nm[HD_KF_MAX_BLOCKS];
    uint32_t frozen_mask;
    uint32_t status;
} v0_kf_output_t;

typedef struct {
    hd_kf_config_t cfg;
    uint8_t n_states;
    uint8_t active_blocks;
    uint8_t block_index[HD_KF_MAX_BLOCKS];
    uint8_t offset_slot;
    uint32_t frozen_mask;
    uint8_t offset_primed;
    uint8_t load_ref_primed;
    float load_ref_nm;
    float x[HD_KF_MAX_STATES];
    float p[HD_KF_MAX_STATES][HD_KF_MAX_STATES];
    uint32_t status_sticky;
    uint32_t reset_count;
    uint32_t bad_input_count;
} v0_kf_t;

/* cfg must have passed hd_kf_config_check. */
void v0_kf_init(v0_kf_t *kf, const hd_kf_config_t *cfg);
void v0_kf_reset(v0_kf_t *kf);
void v0_kf_step(v0_kf_t *kf, const hd_kf_input_t *in, v0_kf_output_t *out);

#endif /* KF_STEP_V0_H */
