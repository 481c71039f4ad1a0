"""The monitor's torque plot: raw / filtered / ripple torque over the last
--window seconds, live (--plot) or written at the end (--plot-png)."""
from __future__ import annotations

import numpy as np

from .monitor_state import MonitorState
from .safeio import UsageError


class Plot:
    """raw / filtered / ripple torque over the last window (matplotlib)."""

    def __init__(self, interactive: bool, title: str):
        import matplotlib
        if not interactive:
            matplotlib.use("Agg")
        import matplotlib.pyplot as plt
        self.plt = plt
        if interactive:
            if matplotlib.get_backend().lower() in ("agg", "pdf", "svg", "ps", "cairo",
                                                    "template"):
                raise UsageError("--plot needs a display (no interactive matplotlib backend); "
                                 "use --plot-png FILE instead")
            plt.ion()
        self.fig, (self.ax, self.ax_r) = plt.subplots(
            2, 1, figsize=(12, 6.5), dpi=100, sharex=True, height_ratios=(3, 1.4))
        self.fig.suptitle(title)
        (self.l_raw,) = self.ax.plot([], [], lw=0.8, color="0.6", label="raw (TorqueRaw)")
        (self.l_filt,) = self.ax.plot([], [], lw=1.2, color="C0", label="filtered (TorqueFiltered)")
        (self.l_rip,) = self.ax_r.plot([], [], lw=1.0, color="C3", label="ripple removed (Ripple)")
        self.ax.set_ylabel("torque [N m]")
        self.ax_r.set_ylabel("ripple [N m]")
        self.ax_r.set_xlabel("device time [s] (telemetry sequence x period)")
        for a in (self.ax, self.ax_r):
            a.grid(True, alpha=0.3)
            a.legend(loc="upper left")
        self.fig.tight_layout()
        self.closed = False
        if interactive:
            self.fig.canvas.mpl_connect("close_event", self._closed)
            self.plt.show(block=False)

    def _closed(self, _event) -> None:
        self.closed = True

    def update(self, state: MonitorState) -> None:
        tr = state.trace
        if not tr["step"]:
            return
        period = state.period_s or 1e-3
        x = np.asarray(tr["step"], float) * period
        for line, key in ((self.l_raw, "raw"), (self.l_filt, "filt"), (self.l_rip, "ripple")):
            line.set_data(x, np.asarray(tr[key], float))
        for a in (self.ax, self.ax_r):
            a.relim()
            a.autoscale_view()

    def pump(self) -> None:
        self.fig.canvas.draw_idle()
        self.fig.canvas.flush_events()

    def save(self, path: str) -> None:
        from .safeio import Outputs
        with Outputs() as out:
            with out.path(path) as tmp:
                self.fig.savefig(tmp, format="png")
            out.commit()
