"""`monitor --foxglove`: the recording's channels served live on a
Foxglove WebSocket (foxglove-sdk, whose server speaks the subprotocol
foxglove.sdk.v1): in Foxglove "Open connection" -> "Foxglove WebSocket"
-> ws://127.0.0.1:8765.  Messages are the same CDR bytes the MCAP gets,
with ros2msg schemas, so a panel set up on a recording works live.  Bound
to 127.0.0.1 unless --foxglove-host says otherwise."""
from __future__ import annotations

from ..safeio import OutputError, UsageError
from . import messages


def _sdk():
    try:
        import foxglove
    except ImportError:
        raise UsageError("--foxglove needs the foxglove-sdk package "
                         "(pip install './tools[foxglove]')") from None
    return foxglove


class Server:
    """A sink like BagOutput: write(topic, msgtype, cdr, stamp_ns)."""

    def __init__(self, host: str, port: int, name: str):
        fg = _sdk()
        self._schema = fg.Schema
        self._channel = fg.Channel
        self.context = fg.Context()
        try:
            self.server = fg.start_server(name=f"hdjoint {name}", host=host, port=port,
                                          context=self.context)
        except Exception as exc:  # noqa: BLE001 - the SDK raises its own error types
            why = " ".join(str(exc).split()) or type(exc).__name__
            raise OutputError(f"foxglove server on {host}:{port}: cannot start: {why}") from None
        self.host = host
        self.channels: dict[str, object] = {}

    @property
    def port(self) -> int:
        return self.server.port

    @property
    def url(self) -> str:
        return f"ws://{self.host}:{self.port}"

    def advertise(self, connections) -> None:
        """Channels for every (topic, msgtype) now: a client sees them all
        at once, before the first message."""
        for topic, msgtype in connections:
            self._open(topic, msgtype)

    def _open(self, topic: str, msgtype: str):
        ch = self.channels.get(topic)
        if ch is None:
            msgdef, _ = messages.TYPESTORE.generate_msgdef(msgtype, ros_version=2)
            schema = self._schema(name=msgtype, encoding="ros2msg", data=msgdef.encode())
            ch = self.channels[topic] = self._channel(topic, schema=schema,
                                                      message_encoding="cdr",
                                                      context=self.context)
        return ch

    def write(self, topic: str, msgtype: str, data: bytes, stamp_ns: int) -> None:
        self._open(topic, msgtype).log(data, log_time=int(stamp_ns))

    def close(self) -> None:
        self.server.stop()

    def abort(self) -> None:
        self.close()
