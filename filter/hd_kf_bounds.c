/* hd_kf_bounds: the step's slow paths, out of its straight line: blocks
 * whose phase was lost restart, and the covariance is brought back within
 * [0, p_max] (hd_kf.h, "Numerics"). */
#include <math.h> /* sqrtf (VSQRT on Cortex-M4F) */

#include "hd_kf_internal.h"

/* Phase lost: the blocks restart from zero with their priors,
 * decorrelated; one pass over P for all of them. */
void hd_kf_restart_lost_blocks(hd_kf_t *kf, uint32_t lost)
{
    const unsigned nb = kf->n_blocks;
    float *p = kf->p;
    for (unsigned s = 0; s < nb; s++) {
        const bool row = (lost & (1u << s)) != 0u;
        if (row) {
            p[0] = p[2] = kf->slot[s].p0_nm2;
            p[1] = 0.0f;
            kf->x[2u * s] = kf->x[2u * s + 1u] = 0.0f;
            keep_block_state(kf, s);
        }
        p += 3;
        for (unsigned t = s + 1u; t < nb; t++, p += 4) {
            if (row || (lost & (1u << t)) != 0u) {
                zero_tiles(p, 1u);
            }
        }
        if (row) {
            p[0] = p[1] = 0.0f;
        }
        p += 2;
    }
}

/* The scale of a variance v against the ceiling: 1 inside [0, p_max],
 * sqrt(p_max / v) above it (counted), 0 below 0 (counted); -1 when v is
 * not a number. */
KF_INLINE float ceiling_scale(hd_kf_t *kf, float v)
{
    const float p_max = kf->cfg.p_max_nm2;
    if (!is_finite(v)) {
        return -1.0f;
    }
    if (v < 0.0f) {
        kf->p_negative_count++;
        return 0.0f;
    }
    if (v > p_max) {
        kf->p_ceiling_count++;
        return sqrtf(p_max / v);
    }
    return 1.0f;
}

/* Slow path, when the probe saw a block or the offset leave the bounds or
 * the state was not finite: a non-finite state or covariance resets the
 * filter; otherwise P <- D P D, D = sqrt(p_max / lambda_max) on both states
 * of a block whose largest eigenvalue is above p_max (the same in every
 * frame, so it is applied in the frames), sqrt(p_max / P_oo) on the
 * offset, and 0 on a block that is not PSD or a negative offset variance.
 * Returns the status bits raised. */
uint32_t hd_kf_bound_covariance(hd_kf_t *kf, float finite_probe)
{
    const unsigned nb = kf->n_blocks;
    float d[HD_KF_MAX_BLOCKS + 1u];
    bool scaled = false;
    if (!is_finite(finite_probe)) {
        return HD_KF_STATUS_RESET;
    }
    float *p = kf->p;
    for (unsigned s = 0; s < nb; s++) {
        const float mid = (p[0] + p[2]) * 0.5f, half = (p[0] - p[2]) * 0.5f;
        const float det = p[0] * p[2] - p[1] * p[1];
        const float lmax = mid + sqrtf(half * half + p[1] * p[1]);
        d[s] = ceiling_scale(kf, (det < 0.0f || mid < 0.0f) ? -1.0f : lmax);
        if (!is_finite(lmax + det)) {
            return HD_KF_STATUS_RESET;
        }
        scaled |= d[s] != 1.0f;
        p += 5u + 4u * (nb - 1u - s);
    }
    d[nb] = ceiling_scale(kf, p[0]);
    if (d[nb] < 0.0f) {
        return HD_KF_STATUS_RESET;
    }
    scaled |= d[nb] != 1.0f;
    if (!scaled) {
        return 0u;
    }
    p = kf->p;
    for (unsigned s = 0; s < nb; s++) {
        const float ds = d[s];
        p[0] *= ds * ds;
        p[1] *= ds * ds;
        p[2] *= ds * ds;
        p += 3;
        for (unsigned t = s + 1u; t < nb; t++, p += 4) {
            const float w = ds * d[t];
            p[0] *= w;
            p[1] *= w;
            p[2] *= w;
            p[3] *= w;
        }
        p[0] *= ds * d[nb];
        p[1] *= ds * d[nb];
        p += 2;
    }
    p[0] *= d[nb] * d[nb];
    return HD_KF_STATUS_P_CLAMPED;
}
