"""The filter model the analysis starts from and augments, and its firmware
forms: the configuration text of docs/design/firmware.md (hdjoint-host --config)
and the equivalent CAN command frames (candump `ID#DATA` notation)."""
from __future__ import annotations

import copy
import math
import struct
from dataclasses import asdict, dataclass, field

import numpy as np

from .. import cfgtext, protocol
from . import cfilter

# Default tuning (hd_kf_config_recommended): each ripple block settles in
# ~RIPPLE_SETTLE_S, the offset state (real torque the expected-torque model
# misses) in ~OFFSET_SETTLE_S.  q = R (ts / settle)^2.
RIPPLE_SETTLE_S = 0.05
OFFSET_SETTLE_S = 0.02
SENSOR_DRIFT_SETTLE_S = 10.0   # offset as a slow sensor-zero estimate
# Floor on the noise level the model is built for: the C filter refuses
# p0 / R > 1e4 (float32 would lose P); 6 mN m keeps the recommended p0
# (0.3 N m^2) inside it.
NOISE_FLOOR_NM = 6e-3
# The motor-current term's keys (firmware/hd_params.def), carried by the model
# under the same names; hdsense current fits them, hd_slow.c runs them.
CURRENT_KEYS = ("current_nm_per_a", "current_coulomb_nm", "current_viscous_nm_s_rad",
                "current_inertia_kgm2", "current_backdrive_nm_per_a", "current_error_nm",
                "current_filter_hz")


def _param_default(key: str) -> float:
    return next(p.default for p in protocol.params() if p.key == key)


@dataclass
class Block:
    lock: str          # motor | output | fixed
    order: float       # cycles per rev, or Hz for fixed
    q_nm2: float

    def label(self) -> str:
        unit = "Hz" if self.lock == "fixed" else "/rev"
        return f"{self.lock} {self.order:g}{unit}"


@dataclass
class ProfileLine:
    """One line of a fixed, angle-referenced artifact profile:
    a cos(order alpha) + b sin(order alpha), alpha the absolute motor or
    output angle of the log [rad] (docs/design/analyze.md "Profile")."""
    lock: str          # motor | output
    order: float       # cycles per rev of that angle
    a_nm: float
    b_nm: float

    @property
    def amplitude_nm(self) -> float:
        return math.hypot(self.a_nm, self.b_nm)


@dataclass
class Model:
    gear_ratio: float
    ts_s: float
    r_nm2: float
    blocks: list[Block] = field(default_factory=list)
    offset_enabled: bool = True
    offset_q_nm2: float = 0.0
    offset_is_sensor_error: bool = False
    p0_nm2: float = 10.0
    output_p0_nm2: float = 10.0
    q_motion_ref_rad: float = 0.0
    p_max_nm2: float = 1e6
    nyquist_fraction: float = 0.9
    offset_jump_nm: float = 0.0
    ripple_load_coeff_per_nm: float = 0.0
    correction_max_nm: float = 0.0
    inertia_kgm2: float = 0.0
    viscous_nm_s_rad: float = 0.0
    coulomb_nm: float = 0.0
    coulomb_vel_eps_rad_s: float = 0.01
    track_bandwidth_hz: float = cfilter.DEFAULT_TRACK_BANDWIDTH_HZ
    # hd_kf output_learn_scale: 0 when the output-locked blocks run a fixed
    # profile (predict and turn, never learn).
    output_learn_scale: float = 1.0
    # The output-locked blocks' fixed angle profile, imported into the C
    # filter at the first sample (hd_kf_profile_import; replay.py).
    profile: list[ProfileLine] = field(default_factory=list)
    # The data-driven floor of the offset q (starting(): the torque's slow
    # changes); kept when R changes.
    offset_q_floor_nm2: float = 0.0
    # The motor-current term (0 nm_per_a: none), from a joint configuration
    # text (with_config_text); defaults are the firmware's.
    current_nm_per_a: float = field(default_factory=lambda: _param_default("current_nm_per_a"))
    current_coulomb_nm: float = field(default_factory=lambda: _param_default("current_coulomb_nm"))
    current_viscous_nm_s_rad: float = field(
        default_factory=lambda: _param_default("current_viscous_nm_s_rad"))
    current_inertia_kgm2: float = field(
        default_factory=lambda: _param_default("current_inertia_kgm2"))
    current_backdrive_nm_per_a: float = field(
        default_factory=lambda: _param_default("current_backdrive_nm_per_a"))
    current_error_nm: float = field(default_factory=lambda: _param_default("current_error_nm"))
    current_filter_hz: float = field(default_factory=lambda: _param_default("current_filter_hz"))

    @classmethod
    def starting(cls, gear_ratio, ts_s, noise_nm, motor_orders, output_orders,
                 inertia_kgm2=0.0, slow_step_nm=0.0):
        """The paper's structure (the given orders) with the project's
        recommended tuning, hd_kf_config_recommended (C), for the measured
        noise level: R = noise^2, q = R (ts/settle)^2, plus its gates/priors.
        One data-driven guard: the offset (real torque the expected torque
        misses) must be able to follow the torque's slow changes, so its q is
        at least the mean square per-step change of the 0.2 s-smoothed torque
        (gravity on a sweeping robot joint changes tens of N m per second)."""
        noise = max(noise_nm, NOISE_FLOOR_NM)
        c = cfilter.recommended_config(ts_s, noise, RIPPLE_SETTLE_S, OFFSET_SETTLE_S)
        m = cls(gear_ratio=gear_ratio, ts_s=ts_s, r_nm2=c.r_nm2, inertia_kgm2=inertia_kgm2)
        for k in cfilter.KfConfig.SCALARS:
            v = getattr(c, k)
            setattr(m, k, bool(v) if k in ("offset_enabled", "offset_is_sensor_error") else float(v))
        m.offset_q_floor_nm2 = slow_step_nm ** 2
        m.offset_q_nm2 = max(m.offset_q_nm2, m.offset_q_floor_nm2)
        q = float(c.blocks[0].q_nm2) if c.block_count else cls.q_for_settle(
            m.r_nm2, ts_s, RIPPLE_SETTLE_S)
        m.blocks = [Block("motor", float(o), q) for o in motor_orders]
        m.blocks += [Block("output", float(o), q) for o in output_orders]
        # The tracker needs w ts <= 0.5 (hd_track.h).
        m.track_bandwidth_hz = min(cfilter.DEFAULT_TRACK_BANDWIDTH_HZ, 0.07 / ts_s)
        return m

    @staticmethod
    def q_for_settle(r_nm2, ts_s, settle_s):
        ratio = min(ts_s / settle_s, 0.5)
        return r_nm2 * ratio * ratio

    def with_noise(self, noise_nm: float) -> "Model":
        """The same model for another noise level: R, the offset q, the jump
        threshold and the p0 caps from hd_kf_config_recommended (C) for that
        noise (the offset q no lower than the data-driven floor of
        starting()), and every block q rescaled with R, i.e. the same settle
        times (a retuned block stays retuned)."""
        c = cfilter.recommended_config(self.ts_s, max(noise_nm, NOISE_FLOOR_NM),
                                       RIPPLE_SETTLE_S, OFFSET_SETTLE_S)
        m = self.copy()
        ratio = float(c.r_nm2) / self.r_nm2
        m.r_nm2 = float(c.r_nm2)
        for b in m.blocks:
            b.q_nm2 *= ratio
        m.offset_q_nm2 = max(float(c.offset_q_nm2), self.offset_q_floor_nm2)
        m.offset_jump_nm = float(c.offset_jump_nm)
        m.p0_nm2 = float(c.p0_nm2)
        m.output_p0_nm2 = float(c.output_p0_nm2)
        return m

    def with_config_text(self, text: str, keys=None) -> "Model":
        """A copy with the values a configuration text gives (hdjoint-host
        --config), as the firmware's own parser reads them (hdtools.cfgtext):
        every key the model carries, or only those in `keys`; a text's block
        lines replace the blocks (unless `keys` is given).  Keys the model
        does not carry are ignored.  ValueError with the parser's message."""
        parsed = cfgtext.parse(text)
        m = self.copy()
        for _line, param, value in parsed.values:
            attr = "offset_enabled" if param.key == "offset" else param.key
            if (keys is not None and param.key not in keys) or attr not in self.__dataclass_fields__:
                continue
            setattr(m, attr, bool(value) if param.type == "BOOL" else float(value))
        if parsed.blocks is not None and keys is None:
            if not all(b.enabled for b in parsed.blocks):
                raise ValueError("a disabled block: the analysis model runs enabled blocks only")
            m.blocks = [Block(b.kind, b.order, b.q_nm2) for b in parsed.blocks]
        return m

    def copy(self) -> "Model":
        return copy.deepcopy(self)

    def to_dict(self) -> dict:
        d = asdict(self)
        d["blocks"] = [asdict(b) for b in self.blocks]
        d["profile"] = [asdict(p) for p in self.profile]
        return d

    # --- C filter -----------------------------------------------------------
    def kf_config(self, ts_s: float | None = None) -> cfilter.KfConfig:
        ts = ts_s or self.ts_s
        cfg = cfilter.default_config(ts)
        for k in cfilter.KfConfig.SCALARS:
            setattr(cfg, k, getattr(self, k))
        cfg.output_learn_scale = self.output_learn_scale
        # held output lines follow the load as the firmware's defaults have them
        for key in ("output_row_follow", "output_row_max"):
            setattr(cfg, key, protocol.param_by_key(key).default)
        for b in self.blocks:
            cfg.add_block(cfilter.LOCK_BY_NAME[b.lock], b.order, b.q_nm2)
        return cfg

    def expected_config(self) -> cfilter.ExpectedConfig:
        return cfilter.ExpectedConfig(self.inertia_kgm2, self.viscous_nm_s_rad,
                                      self.coulomb_nm, self.coulomb_vel_eps_rad_s)

    def current_config(self, ts_s: float | None = None) -> cfilter.CurrentConfig | None:
        """The current term as the firmware forms it (hd_slow_current_config);
        None when the model has none (current_nm_per_a 0)."""
        if not self.current_nm_per_a > 0:
            return None
        term = cfilter.CurrentTerm(self.current_nm_per_a, self.current_coulomb_nm,
                                   self.current_viscous_nm_s_rad, self.current_inertia_kgm2,
                                   self.current_backdrive_nm_per_a, self.current_error_nm)
        return cfilter.current_config(term, self.current_filter_hz, self.gear_ratio,
                                      ts_s or self.ts_s)

    # --- firmware forms -----------------------------------------------------
    def config_text(self) -> str:
        lines = ["# Filter model written by `hdsense analyze` (docs/design/analyze.md).",
                 "# Load with: hdjoint-host --config FILE",
                 f"gear_ratio = {self.gear_ratio:.6g}",
                 f"r_nm2 = {self.r_nm2:.6g}",
                 f"p0_nm2 = {self.p0_nm2:.6g}",
                 f"p_max_nm2 = {self.p_max_nm2:.6g}",
                 f"nyquist_fraction = {self.nyquist_fraction:.6g}",
                 f"offset = {'on' if self.offset_enabled else 'off'}",
                 f"offset_q_nm2 = {self.offset_q_nm2:.6g}",
                 f"offset_is_sensor_error = {'on' if self.offset_is_sensor_error else 'off'}",
                 # The recommended tuning's gates and priors (hd_kf.h "Slow
                 # lines", "Offset jumps"): without them the firmware would
                 # run its defaults, not the model the analysis evaluated.
                 f"output_p0_nm2 = {self.output_p0_nm2:.6g}",
                 f"offset_jump_nm = {self.offset_jump_nm:.6g}",
                 f"q_motion_ref_rad = {self.q_motion_ref_rad:.6g}",
                 f"ripple_load_coeff_per_nm = {self.ripple_load_coeff_per_nm:.6g}",
                 f"correction_max_nm = {self.correction_max_nm:.6g}"]
        for b in self.blocks:
            lines.append(f"block = {b.lock} {b.order:.6g} {b.q_nm2:.6g}")
        lines += [f"inertia_kgm2 = {self.inertia_kgm2:.6g}",
                  f"viscous_nm_s_rad = {self.viscous_nm_s_rad:.6g}",
                  f"coulomb_nm = {self.coulomb_nm:.6g}",
                  f"coulomb_vel_eps_rad_s = {self.coulomb_vel_eps_rad_s:.6g}",
                  f"track_bandwidth_hz = {self.track_bandwidth_hz:.6g}"]
        if self.current_nm_per_a > 0:
            # .9g: float32 round-trips, so the joint runs the term replayed
            lines += [f"{k} = {getattr(self, k):.9g}" for k in CURRENT_KEYS]
        return "\n".join(lines) + "\n"

    def can_commands(self, node_id: int = 1) -> list[dict]:
        """CAN CMD frames (docs/reference/protocol.md) that put this model into a
        running joint: the configuration text translated by canproto (every
        key of the parameter table has a SET_PARAM), as `cansend` strings
        with what each one does.  ValueError if a value cannot travel (an
        order outside 0.01..655.35)."""
        from .. import canproto
        db = canproto.load_db(node_id)
        cmd = db.get_message_by_name("CMD")
        out = []
        for frame in canproto.config_to_commands(self.config_text(), db=db):
            fields = cmd.decode(frame[1], decode_choices=True)
            what = " ".join(f"{k}={v}" for k, v in fields.items() if k != "Token")
            out.append({"candump": canproto.cansend_str(frame), "what": what})
        return out


def slow_step_nm(torque_nm: np.ndarray, ts_s: float, window_s: float = 0.2) -> float:
    """RMS per-sample change of the torque smoothed over window_s (ripple
    above ~1/window_s averages out; load and gravity changes remain)."""
    x = np.asarray(torque_nm, float)
    w = max(1, int(round(window_s / ts_s)))
    if len(x) < 4 * w + 2:
        return 0.0
    # Three passes of the boxcar: one pass leaks a motor line a few per
    # cent (sinc sidelobes), and at 1 kHz that leak's per-sample change
    # (0.0067 N m on the friction scenario, against 0.00012 without the
    # ripple) dwarfs the slow torque and made the offset 2x too agile.
    sm = x
    for _ in range(3):
        if len(sm) < w + 2:
            return 0.0
        c = np.cumsum(np.r_[0.0, sm])
        sm = (c[w:] - c[:-w]) / w
    # Median, not mean: the steps at reversals are the jump gate's business.
    return float(np.sqrt(np.median(np.diff(sm) ** 2)))


def estimate_noise_nm(torque_nm: np.ndarray) -> float:
    """White-noise level from the third difference (removes smooth torque
    and, mostly, ripple well below Nyquist): std(d3) = sigma sqrt(20)."""
    d3 = np.diff(np.asarray(torque_nm, float), 3)
    if len(d3) < 8:
        return float(np.std(torque_nm)) or 1.0
    mad = np.median(np.abs(d3 - np.median(d3))) * 1.4826
    return float(mad / math.sqrt(20.0))
