"""A decoded candump log (canproto.decode_log) -> a Recording: the same
samples `canlog decode --csv` writes (device time, angles interpolated
between TELEM_C counts: hdtools.telemetry.columns), stamped on the host
clock at the first sample's candump time stamp + device time."""
from __future__ import annotations

import math

from .. import protocol, telemetry
from . import messages, stream

_VERSION_OPS = ("VERSION", "INFO")


def items_from_acks(acks: list[dict]) -> dict[str, str]:
    """VERSION / INFO answers (decoded with choices) as {item name: text}."""
    from ..canshared import fmt_item as _fmt_item
    out = {}
    for ack in acks:
        if str(ack["AckOpcode"]) in _VERSION_OPS and str(ack["AckResult"]) == "OK":
            try:
                name = protocol.name_of(protocol.info_items(), int(ack["AckAux"]))
            except (KeyError, ValueError):
                continue
            out[name] = _fmt_item(name, int(ack.get("AckValueU32", ack.get("AckValue", 0))))
    return out


def metadata(res: dict, joint: str) -> dict[str, str]:
    from ..canshared import boot_report
    boots = [boot_report(_raw(b)) for b in res["boots"]]
    return stream.device_metadata(res.get("params", {}), boots, items_from_acks(res["acks"]),
                                  joint, res["node"])


def _raw(d: dict) -> dict:
    """cantools' choice values (NamedSignalValue) back to their numbers."""
    return {k: getattr(v, "value", v) for k, v in d.items()}


def write(res: dict, recording: stream.Recording, cpr=(None, None)) -> int:
    """Every telemetry sample, heartbeat and feed-forward of the log, in
    time order per kind; returns the number of samples."""
    rows = res["telemetry"]
    if not rows:
        return 0
    cols, _ = telemetry.columns(res, *cpr)
    host0_ns = int(round((rows[0]["t_host_s"] - rows[0]["t_s"]) * 1e9))
    gear = res.get("params", {}).get("gear_ratio")
    has_output = "output_angle_rad" in cols
    faults = 0
    for i, r in enumerate(rows):
        s = {k: float(r[k]) for k in messages.SAMPLE_SIGNALS}
        if not r["valid"]:
            s["TorqueRaw"] = s["TorqueFiltered"] = math.nan
        s["stamp_ns"] = host0_ns + int(round(r["t_s"] * 1e9))
        s["motor_angle_rad"] = float(cols["motor_angle_rad"][i])
        s["output_angle_rad"] = float(cols["output_angle_rad"][i]) if has_output else None
        s["output_velocity_rad_s"] = s["MotorVelocity"] / gear if gear else None
        recording.sample(s)
        if int(r["Faults"]) != faults:
            faults = int(r["Faults"])
            recording.diagnostics(s["stamp_ns"], None, faults, {})
    for hb in res["heartbeats"]:
        state, hb_faults, values = messages.heartbeat_values(_raw(hb))
        recording.diagnostics(int(round(hb["t_s"] * 1e9)), state, hb_faults, values)
    for ff in res.get("feedforward", ()):
        recording.value("FfTorque", float(ff["FfTorque"]), int(round(ff["t_s"] * 1e9)))
    return len(rows)


def check_decoded(res: dict, path: str) -> None:
    """The same refusal as `canlog decode` for a log without the node."""
    from ..safeio import UsageError
    if res["nodes"].get(res["node"], 0) == 0:
        raise UsageError(f"{path}: no frames of node {res['node']}")
    if not res["telemetry"]:
        raise UsageError(f"{path}: no telemetry of node {res['node']} (nothing to record)")

