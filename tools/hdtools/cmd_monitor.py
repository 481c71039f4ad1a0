"""`hdsense monitor`: watch one joint live on a CAN bus.

  hdsense monitor can0                         # SocketCAN; Ctrl-C ends
  hdsense monitor can0 --log run.log --plot    # record + live torque plot
  hdsense monitor -i pcan --channel PCAN_USBBUS1 --bitrate 1000000 --node 3
  hdsense monitor can0 --duration 10 --log run.log --plot-png run.png

Shows, once per --interval, the decoded telemetry of one node (raw,
filtered and ripple torque, motor velocity), fault bits by name, the last
heartbeat (state, record statuses), on a board with a drive the control
state (CTRL_STATE: the mode run and asked, torque reference, current
command, the limits that shaped it, flags), telemetry rate, lost telemetry
(sequence gaps), bus load, and how many frames were foreign (other devices,
other joint nodes) or malformed (this node's identifiers with a wrong
length, remote/FD/error frames).  Events (BOOT report, state and fault
changes, control mode and flag changes and each limit the first time it
acts, sequence gaps, answers to commands) are printed as they happen.
Only this node's frames are decoded; a bad frame is counted, never fatal.

--log FILE records every frame on the bus as a `candump -l` log (the
format `hdsense canlog decode` and `hdsense analyze` read), written under a
temporary name in FILE's directory, flushed every half second in whole
lines, and renamed to FILE when the monitor ends.  Unless --passive, the
monitor asks the joint (GET_PARAM) for telemetry_rate_hz, motor_cpr,
output_cpr, gear_ratio and angle_telemetry_every at the start, so the log
carries what its decoding needs.

On SocketCAN the monitor asks the kernel for an 8 MiB receive buffer
(root: always; others: up to net.core.rmem_max, which may be raised with
`sysctl -w net.core.rmem_max=8388608`); the summary shows what it got
(rx_buffer_bytes).  Frames the kernel drops from a full buffer never reach
the monitor: they show as lost telemetry (sequence gaps) only.

--plot opens a live plot of raw / filtered / ripple torque over the last
--window seconds (needs a display); --plot-png FILE writes the same plot
at the end (works headless).

--mcap FILE / --rosbag DIR write the telemetry as ROS 2 messages
(/joint_states, /diagnostics, /hdjoint/JOINT/...; --joint NAME), whole
or not at all; --foxglove serves them live on ws://127.0.0.1:8765
(docs/how-to/ros2.md).

Ends after --duration seconds, on Ctrl-C or SIGTERM, or when the plot
window is closed: the summary is printed, the log renamed, exit 0.
Exit status: 0 ok; 2 bad command line; 3 the log, PNG, MCAP or rosbag2
folder could not be written (temporaries removed; an old FILE is left as
it was) or the Foxglove server could not start;
5 the CAN interface cannot be opened or failed.
"""
from __future__ import annotations

import argparse
import signal
import socket
import sys
import time

import can

from . import protocol
from .canshared import add_bus_arguments, boot_report, node_id as _node, positive as _positive
from .joint import BusError, Joint, NoAnswer, open_bus
from .monitor_log import FLUSH_S, LogRecorder, candump_line
from .monitor_plot import Plot
from .monitor_state import QUERY_PARAMS, MonitorState, classify, frame_bits, malformed_reason
from .safeio import UsageError

# Names other modules and tests import from here (the monitor's parts live
# in monitor_log, monitor_state, monitor_plot, canshared).
__all__ = ["FLUSH_S", "LogRecorder", "MonitorState", "Plot", "QUERY_PARAMS",
           "add_bus_arguments", "boot_report", "candump_line", "classify", "frame_bits",
           "grow_rx_buffer", "malformed_reason", "register", "run"]

# python-can leaves its SocketCAN socket at net.core.rmem_default (~200 KiB:
# about 280 frames, under 0.1 s of 1 kHz telemetry), so a monitor held up
# longer (a plot redraw, a busy machine) lost frames; measured in the VM
# test (tests/vm, docs/how-to/socketcan.md).  8 MiB holds seconds of telemetry.
RX_BUFFER_BYTES = 8 << 20
SO_RCVBUFFORCE = getattr(socket, "SO_RCVBUFFORCE", 33)     # Linux; not in Python 3.11


def grow_rx_buffer(bus) -> int | None:
    """Enlarges the receive buffer of a SocketCAN bus (SO_RCVBUFFORCE as
    root, else SO_RCVBUF, which the kernel caps at net.core.rmem_max);
    returns the size granted, or None for other interfaces."""
    sock = getattr(bus, "socket", None)
    if not isinstance(sock, socket.socket) or sock.family != getattr(socket, "AF_CAN", -1):
        return None
    for option in (SO_RCVBUFFORCE, socket.SO_RCVBUF):
        try:
            sock.setsockopt(socket.SOL_SOCKET, option, RX_BUFFER_BYTES)
            break
        except OSError:
            continue
    return sock.getsockopt(socket.SOL_SOCKET, socket.SO_RCVBUF)


# --------------------------------------------------------------------- run
class _Stop(Exception):
    pass


def _on_sigterm(signum, frame):
    raise _Stop()


def _query(bus, feed, node: int, say) -> None:
    joint = Joint(bus, node, timeout_s=0.3)
    joint.on_frame = feed
    for key in QUERY_PARAMS:
        try:
            joint.get(protocol.param_by_key(key))   # the answer reaches state through feed
        except NoAnswer:
            say(f"node {node}: no answer to GET_PARAM {key} (passive from here)")
            return


def run(args) -> int:
    if args.duration is not None and not args.duration > 0:
        raise UsageError("--duration must be a positive number of seconds")
    channel = args.channel_opt or args.channel
    if not channel:
        raise UsageError("give the CAN interface (e.g. can0) or --channel")
    out = sys.stdout
    tty = out.isatty()

    def say(line: str) -> None:
        out.write(("\r\x1b[K" if tty else "") + line + "\n")
        out.flush()

    state = MonitorState(args.node, args.bitrate, args.window, events=say)
    plot = None
    if args.plot or args.plot_png:
        plot = Plot(interactive=args.plot, title=f"hdsense monitor {channel}")
    bus = open_bus(args.interface, channel, args.bitrate)
    rx_buffer = grow_rx_buffer(bus)
    recorder = None
    from .rosio import cli as rosio_cli
    ros = None
    old_term = signal.getsignal(signal.SIGTERM)
    start = time.monotonic()
    try:
        if args.log:
            recorder = LogRecorder(args.log, channel)
        ros = rosio_cli.MonitorOutputs.open(args, say)
        state.listener = ros.listener if ros else None

        def feed(msg):
            if recorder is not None:
                recorder.write(msg)
            state.feed(msg)

        signal.signal(signal.SIGTERM, _on_sigterm)
        say(f"monitor: {args.interface} {channel}, node "
            f"{args.node if args.node is not None else '(first heard)'}"
            + (f", recording to {args.log}" if args.log else ""))
        next_status = start + args.interval
        next_plot = start
        queried = args.passive
        try:
            while True:
                now = time.monotonic()
                if args.duration is not None and now - start >= args.duration:
                    break
                if plot is not None and plot.closed:
                    break
                try:
                    msg = bus.recv(timeout=0.05)
                except can.CanError as exc:
                    raise BusError(f"{channel}: receive failed: {' '.join(str(exc).split())}") \
                        from None
                if msg is not None:
                    feed(msg)
                if not queried and state.node is not None:
                    queried = True
                    _query(bus, feed, state.node, say)
                    if ros:
                        ros.query(bus, feed, state.node, say)
                if now >= next_status:
                    next_status = now + args.interval
                    line = state.status_line(time.time())
                    if tty:
                        out.write("\r\x1b[K" + line)
                        out.flush()
                    elif not args.quiet:
                        say(line)
                if plot is not None and args.plot and now >= next_plot:
                    next_plot = now + 0.1
                    plot.update(state)
                    plot.pump()
                if recorder is not None and now - recorder.last_flush >= FLUSH_S:
                    recorder.flush()
        except (KeyboardInterrupt, _Stop):
            if tty:
                out.write("\n")
            say("monitor: stopped")
        if recorder is not None:
            recorder.close()
            recorder = None
        if ros:
            ros.close(state)
            ros = None
        if plot is not None and args.plot_png:
            plot.update(state)
            plot.save(args.plot_png)
    finally:
        signal.signal(signal.SIGTERM, old_term)
        if recorder is not None:
            recorder.abort()
        if ros:
            ros.abort()
        bus.shutdown()
    lines = state.summary(time.monotonic() - start)
    if rx_buffer is not None:
        lines.append(f"rx_buffer_bytes = {rx_buffer}")
    if args.log:
        lines.append(f"log = {args.log}")
    if args.plot_png:
        lines.append(f"plot = {args.plot_png}")
    lines += rosio_cli.summary_lines(args)
    out.write("\n".join(lines) + "\n")
    return 0


def register(subparsers) -> None:
    from .cli import version
    p = subparsers.add_parser("monitor", help="watch a joint live on a CAN bus",
                              description=__doc__,
                              formatter_class=argparse.RawDescriptionHelpFormatter)
    p.add_argument("--version", action="version", version=f"hdsense monitor {version()}")
    add_bus_arguments(p, channel_optional=True)
    p.add_argument("--node", type=_node, default=None,
                   help=f"node id {protocol.NODE_MIN}..{protocol.NODE_MAX} "
                        "(default: the first joint heard)")
    p.add_argument("--log", metavar="FILE", help="record every frame as a candump -l log")
    p.add_argument("--duration", type=_positive, default=None, metavar="S",
                   help="stop after S seconds (default: until Ctrl-C)")
    p.add_argument("--interval", type=_positive, default=0.5, metavar="S",
                   help="status line period (default 0.5 s)")
    p.add_argument("--window", type=_positive, default=5.0, metavar="S",
                   help="plot window (default 5 s)")
    p.add_argument("--plot", action="store_true", help="live torque plot (needs a display)")
    p.add_argument("--plot-png", metavar="FILE", help="write the torque plot here at the end")
    from .rosio import cli as rosio_cli
    rosio_cli.add_output_arguments(p, live=True)
    p.add_argument("--passive", action="store_true",
                   help="send nothing (no GET_PARAM queries at the start)")
    p.add_argument("-q", "--quiet", action="store_true",
                   help="no status lines when stdout is not a terminal (events and summary only)")
    p.set_defaults(func=run)
