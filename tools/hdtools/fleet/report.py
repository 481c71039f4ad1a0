"""The fleet report: report.json (for machines), report.html (one row per
joint, flagged joints first, a sparkline per indicator) and report.png (the
same grid), all staged and renamed together (hdtools.safeio.Outputs)."""
from __future__ import annotations

import base64
import html
import io
import json
import math

from ..safeio import Outputs
from . import trends

SPARK_IN = (1.6, 0.45)
SPARK_DPI = 80


def _clean(o):
    if isinstance(o, dict):
        return {k: _clean(v) for k, v in o.items()}
    if isinstance(o, (list, tuple)):
        return [_clean(v) for v in o]
    if isinstance(o, float) and not math.isfinite(o):
        return None
    return o


def document(joint_rows, refused, run, th) -> dict:
    return _clean({"thresholds": th, "rules": trends.RULE_TEXT, "run": run,
                   "flagged": [j["joint"] for j in joint_rows if j["flagged"]],
                   "joints": joint_rows, "refused": refused})


def _sparkline(ax, ind):
    ax.plot(ind["days"], ind["values"], lw=1.0, color="#c0392b" if ind["flagged"] else "#34495e")
    if ind.get("first_flagged_day") is not None:
        ax.axvline(ind["first_flagged_day"], color="#c0392b", lw=0.6, ls=":")
    ax.set_xticks([])
    ax.set_yticks([])
    for s in ax.spines.values():
        s.set_visible(False)


def _row_png(joint) -> bytes:
    import matplotlib
    matplotlib.use("Agg")
    import matplotlib.pyplot as plt
    names = list(joint["indicators"])
    fig, axes = plt.subplots(1, len(names), figsize=(SPARK_IN[0] * len(names), SPARK_IN[1]))
    for ax, name in zip(axes, names):
        _sparkline(ax, joint["indicators"][name])
    fig.subplots_adjust(0.01, 0.05, 0.99, 0.95, wspace=0.1)
    buf = io.BytesIO()
    fig.savefig(buf, format="png", dpi=SPARK_DPI)
    plt.close(fig)
    return buf.getvalue()


def grid_png(joint_rows) -> bytes:
    import matplotlib
    matplotlib.use("Agg")
    import matplotlib.pyplot as plt
    names = list(joint_rows[0]["indicators"]) if joint_rows else []
    nr, nc = max(len(joint_rows), 1), max(len(names), 1)
    fig, axes = plt.subplots(nr, nc, figsize=(SPARK_IN[0] * nc + 1.2, SPARK_IN[1] * nr + 0.8),
                             squeeze=False)
    for i, j in enumerate(joint_rows):
        for k, name in enumerate(names):
            _sparkline(axes[i][k], j["indicators"][name])
            if i == 0:
                axes[i][k].set_title(name, fontsize=6)
        axes[i][0].set_ylabel(j["joint"] + (" !" if j["flagged"] else ""), fontsize=6,
                              rotation=0, ha="right")
    fig.subplots_adjust(0.08, 0.02, 0.99, 0.93, wspace=0.1, hspace=0.15)
    buf = io.BytesIO()
    fig.savefig(buf, format="png", dpi=SPARK_DPI)
    plt.close(fig)
    return buf.getvalue()


def _fmt(ind):
    ch = ind.get("change")
    return "" if ch is None or not math.isfinite(ch) else f"{100 * ch:+.1f} %"


def html_text(doc) -> str:
    rows = doc["joints"]
    names = list(rows[0]["indicators"]) if rows else []
    head = "".join(f"<th>{html.escape(n)}</th>" for n in names)
    body = []
    for j in rows:
        img = base64.b64encode(_row_png(j)).decode()
        changes = " · ".join(f"{html.escape(n)} {_fmt(j['indicators'][n])}" for n in j["alarms"])
        body.append(f"<tr class='{'flag' if j['flagged'] else ''}'><td>{html.escape(j['joint'])}"
                    f"</td><td>{j['records']}</td><td>{j['hours']:.2f}</td>"
                    f"<td>{changes or 'ok'}</td><td colspan='{len(names)}'>"
                    f"<img src='data:image/png;base64,{img}'></td></tr>")
    refused = "".join(f"<li>{html.escape(r['path'])}: {html.escape(r['message'])}</li>"
                      for r in doc["refused"])
    return ("<!doctype html><meta charset='utf-8'><title>hdsense fleet</title>"
            "<style>body{font:13px sans-serif}td,th{padding:2px 6px;border-bottom:1px solid #ddd}"
            "tr.flag td{background:#fdecea}</style>"
            f"<h1>Fleet: {len(doc['flagged'])} of {len(rows)} joints flagged</h1>"
            f"<p>{html.escape(json.dumps(doc['run']))}</p>"
            f"<table><tr><th>joint</th><th>logs</th><th>hours</th><th>alarms</th>{head}</tr>"
            + "".join(body) + "</table>"
            + (f"<h2>Refused logs</h2><ul>{refused}</ul>" if refused else ""))


def write(store_root, doc) -> list:
    names = ["report.json", "report.html", "report.png"]
    with Outputs() as out:
        out.write_text(store_root / names[0], json.dumps(doc, indent=1) + "\n")
        out.write_text(store_root / names[1], html_text(doc))
        out.write_bytes(store_root / names[2], grid_png(doc["joints"]))
        out.commit()
    return [store_root / n for n in names]
