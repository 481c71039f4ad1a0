"""hdsense device on a CAN interface that fails while the tool waits: one
line on stderr and exit 5 (BusError), never an "internal error" (exit 4)
or a traceback.  The bus is a stand-in that answers one command and then
fails, at each of the tool's waits (an ACK, the BOOT frame after REBOOT,
the drain before REBOOT)."""
from __future__ import annotations

import can
import pytest

from hdtools import canproto, cli, cmd_device, protocol


class FailingBus:
    """Answers the first `answers` commands with ACK OK (after `fail_drain`
    a failing poll), then every recv raises can.CanError."""

    def __init__(self, answers: int, fail_drain: bool = False):
        self.db = canproto.load_db(1)
        self.answers, self.fail_drain = answers, fail_drain
        self.queue: list[can.Message] = []

    def send(self, msg, timeout=None):
        if self.answers > 0:
            self.answers -= 1
            ack = self.db.get_message_by_name("ACK")
            codes = {e.name: e.code for e in protocol.results()}
            data = ack.encode({"AckOpcode": msg.data[0], "AckToken": msg.data[1],
                               "AckResult": codes["OK"], "AckAux": 0, "AckValue": 0.0},
                              strict=False)
            self.queue.append(can.Message(arbitration_id=ack.frame_id, is_extended_id=True,
                                          data=data))

    def recv(self, timeout=None):
        if self.queue:
            return self.queue.pop(0)
        if timeout == 0 and not self.fail_drain:
            return None
        raise can.CanError("Network is down [Error Code 100]")

    def shutdown(self):
        pass


@pytest.mark.parametrize("answers, fail_drain, action", [
    (0, False, ["get", "gear_ratio"]),     # the wait for an ACK
    (1, False, ["reboot"]),                # the wait for BOOT after REBOOT's ACK
    (0, True, ["reboot"]),                 # the drain before REBOOT
])
def test_bus_failing_while_waiting_is_one_line_exit_5(monkeypatch, capsys, answers, fail_drain,
                                                      action):
    monkeypatch.setattr(cmd_device, "open_bus", lambda *a, **k: FailingBus(answers, fail_drain))
    rc = cli.main(["device", "vcan0"] + action)
    err = capsys.readouterr().err
    assert rc == 5, err
    assert len(err.strip().splitlines()) == 1
    assert "receive failed: Network is down" in err and "internal error" not in err


def test_device_set_bad_value_names_the_key_not_a_line(monkeypatch, capsys):
    # the configuration-text check (canproto.param_value) without its
    # "line N:" prefix, which belongs to a file
    monkeypatch.setattr(cmd_device, "open_bus", lambda *a, **k: FailingBus(0))
    rc = cli.main(["device", "vcan0", "set", "r_nm2", "abc"])
    err = capsys.readouterr().err
    assert rc == 2 and err.strip() == \
        "hdsense device: r_nm2 = abc: value is not a number (a finite decimal)"
