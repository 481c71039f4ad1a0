"""The ROS 2 outputs' command-line options (shared by `monitor` and
`canlog convert`) and `canlog convert` itself."""
from __future__ import annotations

import argparse
import sys

from ..safeio import UsageError
from . import topics

DEFAULT_JOINT = "joint1"


def _joint(text: str) -> str:
    try:
        return topics.check_joint_name(text)
    except ValueError as exc:
        raise argparse.ArgumentTypeError(str(exc)) from None


def _port(text: str) -> int:
    try:
        port = int(text, 10)
    except ValueError:
        raise argparse.ArgumentTypeError(f"{text!r} is not a port number") from None
    if not 0 <= port <= 65535:
        raise argparse.ArgumentTypeError(f"port {port} outside 0..65535")
    return port


def add_output_arguments(p, live: bool = False) -> None:
    p.add_argument("--mcap", metavar="FILE.mcap",
                   help="write ROS 2 messages (CDR) to this MCAP file (docs/how-to/ros2.md)")
    p.add_argument("--rosbag", metavar="DIR",
                   help="write a rosbag2 folder (metadata.yaml + .mcap) that ros2 bag play "
                        "takes; DIR must not exist")
    p.add_argument("--joint", type=_joint, default=DEFAULT_JOINT, metavar="NAME",
                   help=f"joint name in JointState.name and the topics (default {DEFAULT_JOINT})")
    if live:
        p.add_argument("--foxglove", action="store_true",
                       help="serve the same channels live on a Foxglove WebSocket "
                            "(needs the foxglove-sdk package)")
        p.add_argument("--foxglove-host", default="127.0.0.1", metavar="ADDR",
                       help="address the live server binds (default 127.0.0.1, this machine "
                            "only)")
        p.add_argument("--foxglove-port", type=_port, default=8765, metavar="PORT",
                       help="its port (default 8765; 0: any free port, printed)")


def open_outputs(args, metadata: dict | None = None) -> list:
    """The BagOutputs the options ask for (none: an empty list)."""
    from .bagout import BagOutput
    if args.mcap and args.rosbag and args.mcap == args.rosbag:
        raise UsageError("--mcap and --rosbag name the same path")
    outs = []
    try:
        if args.mcap:
            outs.append(BagOutput(args.mcap, "mcap", metadata))
        if args.rosbag:
            outs.append(BagOutput(args.rosbag, "rosbag2", metadata))
    except Exception:
        for o in outs:
            o.abort()
        raise
    return outs


def convert(args) -> int:
    from .. import canproto
    from . import convert as conv, messages, stream
    if not args.mcap and not args.rosbag:
        raise UsageError("give --mcap FILE.mcap and/or --rosbag DIR")
    res = canproto.decode_log(args.log, args.node, args.rate)
    conv.check_decoded(res, args.log)
    outs = open_outputs(args, conv.metadata(res, args.joint))
    rec = stream.Recording(messages.Encoder(args.joint, res["node"]), outs)
    try:
        n = conv.write(res, rec, args.cpr or (None, None))
        rec.close()
    except BaseException:
        rec.abort()
        raise
    lines = [f"log = {args.log}", f"node = {res['node']}", f"joint = {args.joint}",
             f"samples = {n}", f"lost_telemetry = {res['lost_telemetry']}",
             f"messages = {sum(o.count for o in outs)}"]
    lines += [f"{o.kind} = {o.target}" for o in outs]
    sys.stdout.write("\n".join(lines) + "\n")
    return 0


class MonitorOutputs:
    """`monitor --mcap / --rosbag / --foxglove`: the Recording fed by
    MonitorState's listener, the device's answers for the metadata."""

    def __init__(self, args, sinks: list, server=None):
        from . import messages, stream
        self.args, self.server = args, server
        self.outputs = [s for s in sinks if s is not server]
        self.recording = stream.Recording(messages.Encoder(args.joint, 0), sinks)
        if server is not None:
            server.advertise(self.recording.encoder.connections())
        self.listener = stream.Live(self.recording)
        self.items: dict[str, str] = {}

    @classmethod
    def open(cls, args, say) -> "MonitorOutputs | None":
        if not (args.mcap or args.rosbag or args.foxglove):
            return None
        sinks = open_outputs(args)
        server = None
        if args.foxglove:
            from . import live
            try:
                server = live.Server(args.foxglove_host, args.foxglove_port, args.joint)
            except Exception:
                for s in sinks:
                    s.abort()
                raise
            sinks.append(server)
            say(f"foxglove: {server.url} (in Foxglove: Open connection, Foxglove WebSocket)")
        return cls(args, sinks, server)

    def query(self, bus, feed, node: int, say) -> None:
        """VERSION and INFO items for the metadata (the parameters come with
        the monitor's own queries and every GET_PARAM answer seen)."""
        from .. import protocol
        from ..canshared import fmt_item as _fmt_item
        from ..joint import Joint, NoAnswer
        self.recording.encoder.node = node
        if not (self.args.mcap or self.args.rosbag):
            return
        joint = Joint(bus, node, timeout_s=0.3)
        joint.on_frame = feed
        for e in protocol.info_items():
            try:
                ack = joint.item(e.name)
            except NoAnswer:
                say(f"node {node}: no answer to {e.name} (the metadata lacks it)")
                return
            if ack.ok:
                self.items[e.name] = _fmt_item(e.name, int(ack.value))

    def close(self, state) -> None:
        from . import stream
        self.listener.flush(state)
        node = state.node if state.node is not None else 0
        meta = stream.device_metadata(state.params, list(state.boots), self.items,
                                      self.args.joint, node)
        for o in self.outputs:
            o.metadata.update(meta)
        self.recording.close()

    def abort(self) -> None:
        self.recording.abort()


def summary_lines(args) -> list[str]:
    out = []
    if getattr(args, "mcap", None):
        out.append(f"mcap = {args.mcap}")
    if getattr(args, "rosbag", None):
        out.append(f"rosbag2 = {args.rosbag}")
    return out
