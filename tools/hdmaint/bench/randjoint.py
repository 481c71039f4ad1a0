"""Randomly drawn joints (issue 21): the space of joints every accuracy claim
of the random-joint benchmark holds over, and the scenario files of one
joint's commissioning run and its operation.

A joint is drawn from a seed with numpy's PCG64: every range is in RANGES
(one place; docs/results/random-joints.md's range table is rendered from it).  The
declared lines are the firmware's default model (motor orders 2 and 4,
output order 1), each with a uniform phase; an undeclared effect (one of
UNDECLARED) is added only when asked for, and so are load-modulated lines
(a drawn ripple_load_coeff_per_nm).

Seeds: the fixes of issue 21 were developed on TUNE_SEEDS; the benchmark
reports REPORT_SEEDS (disjoint), and the CI test runs a few of those.
"""
from __future__ import annotations

import math
from dataclasses import dataclass, field
from pathlib import Path

import numpy as np

TUNE_SEEDS = range(0, 1000)
REPORT_SEEDS = range(100_000, 101_000)

RANGES = {
    "gear_ratio": (50.0, 160.0),
    "line_amplitude_nm": (0.2, 1.5),
    "viscous_nm_s_rad": (0.0, 2.0),
    "coulomb_nm": (0.0, 1.5),
    "noise_nm": (0.02, 0.05),
    "load_inertia_kgm2": (0.02, 0.2),
    "commission_speed_rad_s": (1.5, 2.5),
    "operate_speed_rad_s": (0.3, 3.0),
    "operate_segment_s": (3.0, 9.0),
    "load_constant_nm": (-1.0, 1.0),
    "load_sine_amplitude_nm": (0.2, 1.2),
    "load_sine_period_s": (4.0, 40.0),
    "load_step_nm": (-1.5, 1.5),
    "undeclared_amplitude_nm": (0.2, 0.6),
    # load-modulated lines (when drawn): every motor and output line grows
    # as 1 + c |T_true| (hdsim's law, docs/reference/sim.md); 0.1 doubles a line at
    # 10 N m, about the largest load an operating plan here reaches
    "ripple_load_coeff_per_nm": (0.02, 0.1),
}
ENCODER_CPRS = (4096, 16384)
LOAD_SINES = (1, 3)                 # how many slow load sines, inclusive
DECLARED = (("motor", 2), ("motor", 4), ("output", 1))
UNDECLARED = (("output", 2), ("output", 3), ("motor", 1), ("motor", 3), ("motor", 6),
              ("fixed", 50))
COMMISSION_REVS = 3.2               # output revolutions each way (docs/design/slow-torque.md: >= 3)
OPERATE_S = 60.0
RAMP_S = 0.5

# What every drawn joint shares: the demo's bridge and converter.
FIXED_LINES = (
    "ts_s = 0.001",
    "bridge.psi0 = 3.8e-5",
    "bridge.placement_error_rad = 0.001, -0.0005, 0.0008, 0.0002",
    "adc_bits = 16",
    "adc_range_v = 10",
)


@dataclass
class Line:
    kind: str          # motor | output | fixed
    order: float       # cycles per rev, or Hz (fixed)
    amplitude_nm: float
    phase_rad: float

    def ini(self) -> str:
        return (f"ripple = {self.kind} : {self.order:g} : {self.amplitude_nm:.6g} : "
                f"{self.phase_rad:.6g}")


@dataclass
class Joint:
    seed: int
    gear_ratio: float
    lines: list
    viscous_nm_s_rad: float
    coulomb_nm: float
    noise_nm: float
    load_inertia_kgm2: float
    motor_cpr: int
    output_cpr: int
    commission_speed_rad_s: float
    operate_plan: list                 # [(t_s, output rad/s)] breakpoints
    load_constant_nm: float
    load_sines: list                   # [(N m, s, rad)]
    load_step: tuple                   # (t_s, N m)
    undeclared: Line | None = None
    ripple_load_coeff_per_nm: float = 0.0
    extra: dict = field(default_factory=dict)

    @property
    def name(self) -> str:
        u = "" if self.undeclared is None else (
            f"+{self.undeclared.kind}{self.undeclared.order:g}")
        c = self.ripple_load_coeff_per_nm
        return f"j{self.seed}{u}" + (f"+load{c:.3f}" if c > 0 else "")

    def joint_lines(self) -> list[str]:
        """The joint itself (what stays from commissioning to operation)."""
        out = [f"gear_ratio = {self.gear_ratio:.6g}",
               f"viscous_nm_s_rad = {self.viscous_nm_s_rad:.6g}",
               f"coulomb_nm = {self.coulomb_nm:.6g}",
               f"noise_nm = {self.noise_nm:.6g}",
               f"load_inertia_kgm2 = {self.load_inertia_kgm2:.6g}",
               f"encoder_cpr = {self.motor_cpr}",
               f"output_encoder_cpr = {self.output_cpr}", *FIXED_LINES]
        out += [ln.ini() for ln in self.lines]
        if self.ripple_load_coeff_per_nm > 0:
            out.append(f"ripple_load_coeff_per_nm = {self.ripple_load_coeff_per_nm:.6g}")
        if self.undeclared is not None:
            out.append(self.undeclared.ini())
        return out

    def commissioning_ini(self, seed_offset: int = 1) -> str:
        """The commissioning motion of docs/design/slow-torque.md: no load, constant
        speed, COMMISSION_REVS output revolutions each way."""
        w = self.commission_speed_rad_s * self.gear_ratio
        leg = COMMISSION_REVS * 2 * math.pi / self.commission_speed_rad_s
        t1, t2 = RAMP_S + leg, 2 * RAMP_S + 2 * leg
        prof = f"0:0, {RAMP_S:g}:{w:.6g}, {t1:.6g}:{w:.6g}, {t1 + RAMP_S:.6g}:{-w:.6g}, " \
               f"{t2:.6g}:{-w:.6g}"
        return _ini(f"random joint {self.seed}: commissioning", [
            f"duration_s = {t2:.6g}", f"seed = {self.seed * 10 + seed_offset}",
            f"motor_speed_profile = {prof}"] + self.joint_lines())

    def operating_ini(self, seed_offset: int = 2) -> str:
        seed_offset += 10 * int(self.extra.get("day", 0))
        """OPERATE_S of operation: the drawn speed plan and unknown slow loads."""
        prof = ", ".join(f"{t:.6g}:{v * self.gear_ratio:.6g}" for t, v in self.operate_plan)
        ts, step = self.load_step
        c = self.load_constant_nm
        motion = [f"duration_s = {OPERATE_S:g}", f"seed = {self.seed * 10 + seed_offset}",
                  f"motor_speed_profile = {prof}",
                  f"load_torque_profile = 0:{c:.6g}, {ts:.6g}:{c:.6g}, "
                  f"{ts + 0.2:.6g}:{c + step:.6g}"]
        motion += [f"load_sine = {a:.6g} : {p:.6g} : {ph:.6g}" for a, p, ph in self.load_sines]
        return _ini(f"random joint {self.seed}: operation", motion + self.joint_lines())

    def another_day(self, day: int = 1) -> "Joint":
        """The same joint (lines, friction, encoders, undeclared effect) on
        another day: its own operating plan and slow loads, drawn from their
        own stream."""
        from dataclasses import replace
        rng = np.random.Generator(np.random.PCG64([self.seed, 100 + day]))
        return replace(self, seed=self.seed, operate_plan=_speed_plan(rng),
                       load_constant_nm=_u(rng, "load_constant_nm"),
                       load_sines=_load_sines(rng),
                       load_step=(float(rng.uniform(10.0, OPERATE_S - 10.0)),
                                  _u(rng, "load_step_nm")),
                       extra={"day": day})

    def describe(self) -> dict:
        d = {"seed": self.seed, "gear_ratio": self.gear_ratio,
             "lines": [vars(ln) for ln in self.lines],
             "viscous_nm_s_rad": self.viscous_nm_s_rad, "coulomb_nm": self.coulomb_nm,
             "noise_nm": self.noise_nm, "motor_cpr": self.motor_cpr,
             "output_cpr": self.output_cpr,
             "commission_speed_rad_s": self.commission_speed_rad_s}
        if self.undeclared is not None:
            d["undeclared"] = vars(self.undeclared)
        if self.ripple_load_coeff_per_nm > 0:
            d["ripple_load_coeff_per_nm"] = self.ripple_load_coeff_per_nm
        return d


def _ini(title: str, lines: list[str]) -> str:
    return f"# {title} (generated by hdtools.bench.randjoint)\n" + "\n".join(lines) + "\n"


def _u(rng, key):
    lo, hi = RANGES[key]
    return float(rng.uniform(lo, hi))


def _speed_plan(rng) -> list:
    """Segments of constant output speed (|v| in the operating range; the
    direction changes at least every other segment) joined by RAMP_S ramps."""
    plan, t, sign = [(0.0, 0.0)], 0.0, 1.0
    for k in range(10_000):
        if t + RAMP_S >= OPERATE_S - 1.0:
            break
        if k % 2 == 1 or rng.uniform() < 0.5:
            sign = -sign
        v = sign * _u(rng, "operate_speed_rad_s")
        plan.append((t + RAMP_S, v))
        t += RAMP_S + _u(rng, "operate_segment_s")
        plan.append((min(t, OPERATE_S), v))
    if plan[-1][0] < OPERATE_S:
        plan.append((OPERATE_S, plan[-1][1]))
    return plan


def _load_sines(rng) -> list:
    return [(_u(rng, "load_sine_amplitude_nm"), _u(rng, "load_sine_period_s"),
             float(rng.uniform(-math.pi, math.pi)))
            for _ in range(int(rng.integers(LOAD_SINES[0], LOAD_SINES[1] + 1)))]


def draw(seed: int, undeclared: bool | int = False, loaded: bool = False) -> Joint:
    """The joint of this seed; undeclared: False (declared lines only), True
    (one undeclared effect drawn from UNDECLARED) or an index into it;
    loaded: its lines grow with the load (a drawn ripple_load_coeff_per_nm)."""
    rng = np.random.Generator(np.random.PCG64(seed))
    lines = [Line(k, o, _u(rng, "line_amplitude_nm"), float(rng.uniform(-math.pi, math.pi)))
             for k, o in DECLARED]
    j = Joint(
        seed=seed, gear_ratio=round(_u(rng, "gear_ratio"), 3), lines=lines,
        viscous_nm_s_rad=_u(rng, "viscous_nm_s_rad"), coulomb_nm=_u(rng, "coulomb_nm"),
        noise_nm=_u(rng, "noise_nm"), load_inertia_kgm2=_u(rng, "load_inertia_kgm2"),
        motor_cpr=int(rng.choice(ENCODER_CPRS)), output_cpr=int(rng.choice(ENCODER_CPRS)),
        commission_speed_rad_s=_u(rng, "commission_speed_rad_s"),
        operate_plan=_speed_plan(rng), load_constant_nm=_u(rng, "load_constant_nm"),
        load_sines=_load_sines(rng),
        load_step=(float(rng.uniform(10.0, OPERATE_S - 10.0)), _u(rng, "load_step_nm")))
    # The undeclared effect is drawn last, from its own stream, so a joint
    # with it is the same joint as without.
    u_rng = np.random.Generator(np.random.PCG64([seed, 21]))
    if undeclared is not False:
        idx = int(u_rng.integers(len(UNDECLARED))) if undeclared is True else int(undeclared)
        kind, order = UNDECLARED[idx]
        j.undeclared = Line(kind, float(order), _u(u_rng, "undeclared_amplitude_nm"),
                            float(u_rng.uniform(-math.pi, math.pi)))
    if loaded:
        j.ripple_load_coeff_per_nm = _u(np.random.Generator(np.random.PCG64([seed, 23])),
                                        "ripple_load_coeff_per_nm")
    return j


def write(joint: Joint, wd: Path) -> tuple[Path, Path]:
    """The joint's commissioning and operating scenario files in wd."""
    wd.mkdir(parents=True, exist_ok=True)
    com, op = wd / f"{joint.name}_commission.ini", wd / f"{joint.name}_operate.ini"
    com.write_text(joint.commissioning_ini())
    op.write_text(joint.operating_ini())
    return com, op


def ranges_table() -> list[str]:
    """The drawing ranges as a Markdown table (docs/results/random-joints.md)."""
    rows = ["| quantity | drawn from |", "|---|---|"]
    for k, (lo, hi) in RANGES.items():
        rows.append(f"| `{k}` | uniform {lo:g} .. {hi:g} |")
    rows.append(f"| motor / output encoder | one of {', '.join(map(str, ENCODER_CPRS))} counts |")
    rows.append(f"| declared lines | {', '.join(f'{k} {o}' for k, o in DECLARED)}: "
                "amplitude as above, phase uniform on the circle |")
    rows.append(f"| slow load sines | {LOAD_SINES[0]}-{LOAD_SINES[1]}, phase uniform, plus a "
                "constant and one 0.2 s step |")
    rows.append(f"| undeclared effect (one, when drawn) | "
                f"{', '.join(f'{k} {o:g}' + (' Hz' if k == 'fixed' else '') for k, o in UNDECLARED)}"
                " |")
    rows.append("| load-modulated lines (when drawn) | every motor and output line times "
                "1 + `ripple_load_coeff_per_nm` \\|T_true\\| (hdsim) |")
    return rows
