"""Plots raw torque, filtered torque and truth from hdjoint-host's CSV.

  python tools/hdtools/demo_plot.py samples.csv demo.png [--zoom T0 T1] [--told TEXT]

--told: what the firmware was told (printed under the title: the demo
never hands it the simulated plant's parameters).
"""
from __future__ import annotations

import argparse
import sys

import numpy as np


def main(argv: list[str] | None = None) -> int:
    ap = argparse.ArgumentParser(description=__doc__)
    ap.add_argument("csv")
    ap.add_argument("png")
    ap.add_argument("--zoom", nargs=2, type=float, default=[5.0, 5.2], metavar=("T0", "T1"))
    ap.add_argument("--told", default="", help="what the firmware was told (subtitle)")
    args = ap.parse_args(argv)
    import matplotlib
    matplotlib.use("Agg")
    import matplotlib.pyplot as plt

    d = np.genfromtxt(args.csv, delimiter=",", names=True)
    if d.size == 0:
        print(f"demo_plot: {args.csv} has no samples", file=sys.stderr)
        return 1
    t = d["t_s"]
    fig, axes = plt.subplots(2, 1, figsize=(10, 7))
    for ax, sel in ((axes[0], np.ones_like(t, dtype=bool)),
                    (axes[1], (t >= args.zoom[0]) & (t <= args.zoom[1]))):
        ax.plot(t[sel], d["torque_raw_nm"][sel], lw=0.6, color="0.6", label="raw (measured)")
        ax.plot(t[sel], d["torque_filtered_nm"][sel], lw=0.9, color="C0", label="filtered (firmware)")
        if np.isfinite(d["torque_true_nm"]).any():
            ax.plot(t[sel], d["torque_true_nm"][sel], lw=0.9, ls="--", color="C3", label="truth")
        ax.set_xlabel("time [s]")
        ax.set_ylabel("torque [N m]")
        ax.grid(alpha=0.3)
    title = "Ripple cancellation in the firmware ISR (simulated joint)"
    axes[0].set_title(title + (f"\nfirmware told: {args.told}" if args.told else ""))
    axes[1].set_title(f"zoom {args.zoom[0]:g}-{args.zoom[1]:g} s")
    axes[0].legend(loc="lower right")
    fig.tight_layout()
    fig.savefig(args.png, dpi=110)
    return 0


if __name__ == "__main__":
    sys.exit(main())
