/* hd_artifact: the narrowband artifact estimate (hd_artifact.h has the
 * equations). */
#include "hd_artifact.h"

#include <stddef.h>

#include "hd_ctrl_trig.h"

#define TWO_PI_F 6.28318530717958647692f
#define INV_TWO_PI_F 0.15915494309189533577f
#define ANGLE_MAX_RAD 1.0e6f /* beyond: not an angle the wrap can keep precise */

void hd_artifact_reset(hd_artifact_t *t)
{
    for (unsigned k = 0; k <= HD_ARTIFACT_ORDER_MAX; k++) {
        t->re[k] = 0.0f;
        t->im[k] = 0.0f;
    }
}

void hd_artifact_remask(hd_artifact_t *t, uint8_t mask)
{
    t->top = 0u;
    for (unsigned k = 1; k <= HD_ARTIFACT_ORDER_MAX; k++) {
        const unsigned bit = 1u << (k - 1u);
        if ((mask & bit) == 0u) {
            t->re[k] = 0.0f;
            t->im[k] = 0.0f;
        } else {
            t->top = (uint8_t)k;
        }
    }
    t->mask = mask;
}

void hd_artifact_init(hd_artifact_t *t, uint8_t mask, float corner_hz, float ts_s)
{
    t->gain = TWO_PI_F * corner_hz * ts_s;
    hd_artifact_reset(t);
    hd_artifact_remask(t, mask);
}

/* x in [-pi, pi] for |x| <= ANGLE_MAX_RAD (the caller checks). */
static float wrap_pi(float x)
{
    const float turns = x * INV_TWO_PI_F;
    const float n = (float)(int32_t)(turns + (turns >= 0.0f ? 0.5f : -0.5f));
    const float w = x - n * TWO_PI_F;
    return w > 3.14159265f ? 3.14159265f : (w < -3.14159265f ? -3.14159265f : w);
}

float hd_artifact_step(hd_artifact_t *t, float a_nm, float motor_angle_rad, float m)
{
    if (!(motor_angle_rad >= -ANGLE_MAX_RAD && motor_angle_rad <= ANGLE_MAX_RAD)) {
        return t->re[0];
    }
    const float x = wrap_pi(motor_angle_rad);
    float s1, c1;
    sincos_quadrant(x, &s1, &c1);
    /* cos and sin of k theta by complex multiplication: one evaluation of
     * the series per tick, the orders by rotation */
    float ck[HD_ARTIFACT_ORDER_MAX + 1u], sk[HD_ARTIFACT_ORDER_MAX + 1u];
    ck[0] = 1.0f, sk[0] = 0.0f;
    float est = t->re[0];
    for (unsigned k = 1; k <= t->top; k++) { /* top <= HD_ARTIFACT_ORDER_MAX */
        ck[k] = ck[k - 1u] * c1 - sk[k - 1u] * s1;
        sk[k] = sk[k - 1u] * c1 + ck[k - 1u] * s1;
        if ((t->mask & (1u << (k - 1u))) != 0u) {
            est += t->re[k] * ck[k] - t->im[k] * sk[k];
        }
    }
    const float e = a_nm - est;
    if (!(e - e == 0.0f)) { /* a_nm not finite: hold */
        return est;
    }
    const float w = m < 0.0f ? 0.0f : (m > 1.0f ? 1.0f : m);
    const float g = t->gain * w * e;
    t->re[0] += g;
    for (unsigned k = 1; k <= t->top; k++) {
        if ((t->mask & (1u << (k - 1u))) != 0u) {
            t->re[k] += 2.0f * g * ck[k];
            t->im[k] -= 2.0f * g * sk[k];
        }
    }
    return est;
}
