"""The tuning method run on a joint from what a test on it can measure
(the autotuned row of docs/results/control-random.md): control_tune's
method from the firmware's defaults, in the conditions a bench without a
moving dynamometer can hold a joint in, on the plant as the feedback sees
it (no true torque), the wall contact judged on the filtered torque."""
from __future__ import annotations

import dataclasses

from . import control
from . import control_loop as cl
from . import control_tune as ct

AUTOTUNED = "autotuned"
# What a test on the joint itself can hold it in without a dynamometer: the
# output clamped (the dynamometer holding it at rest), pressed against a
# stiff wall, free.  The moving speeds are judged, not tuned on.
CONDITIONS = (str(control.SPEEDS_RAD_S[0]), "wall", "free")


def measured_loop(v: cl.Variant, scene: cl.Scene) -> cl.Response:
    """The loop and the plant as a test on the joint can measure them: the
    feedback's torque per drive current; the tracking the tuning predicts is
    of that feedback, not of the simulation's true torque (none is seen)."""
    r = cl.measure_loop(v, scene)
    return dataclasses.replace(r, true_plant=r.plant)


def autotune(v: cl.Variant) -> tuple[cl.Variant, dict]:
    """control_tune's method run on the joint itself from the firmware's
    defaults: CONDITIONS, the measured plant (measured_loop), the
    wall contact judged on the filtered torque; what it leaves (the defaults
    when nothing it checked holds) and its summary."""
    t = dataclasses.replace(v, key=AUTOTUNED)
    res = ct.tune(t, CONDITIONS, measure=measured_loop,
                  contact=control.wall_check(measured=True))
    return t, {"met": bool(res.get("met")), "fallback": bool(res.get("fallback")),
               "rank": res.get("rank"), "kp": t.kp, "ki_per_s": t.ki, "kd_s": t.kd}
