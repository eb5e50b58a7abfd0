"""The replay format, the recorder and the hidapi transport's diagnosis (no device here)."""

from __future__ import annotations

import errno
import io
import os
import sys
from types import SimpleNamespace

import pytest

from btf_addon.controllers import hid_transport, replay
from btf_addon.controllers.transport import (
    ControllerDisconnectedError,
    ControllerError,
    DevicePermissionError,
    DriverBusyError,
    NoDeviceError,
)

RECORDING = """\
# a Wiimote session: comments and blank lines are allowed

{"t": 0.0, "dir": "out", "hex": "1110"}
{"t": 0.004, "dir": "in", "hex": "20 0000 10 0000 c8"}
{"t": 0.010, "dir": "in", "hex": "300800"}
"""


def test_replay_plays_inputs_in_order_and_records_writes(tmp_path):
    path = tmp_path / "session.jsonl"
    path.write_text(RECORDING)
    transport = replay.ReplayTransport.from_file(path)
    assert transport.read(0) == bytes.fromhex("200000100000c8")
    assert transport.now() == 0.004
    transport.write(b"\x12\x04\x37")
    assert transport.read(0) == b"\x30\x08\x00"
    with pytest.raises(ControllerDisconnectedError, match="ended"):
        transport.read(0)
    assert transport.written == [replay.Record(0.004, replay.OUT, b"\x12\x04\x37")]


def test_realtime_replay_waits_for_the_timestamp():
    transport = replay.ReplayTransport(
        [
            replay.Record(0.0, replay.IN, b"\x30\x00\x00"),
            replay.Record(60.0, replay.IN, b"\x30\x00\x08"),
        ],
        realtime=True,
    )
    assert transport.read(0) == b"\x30\x00\x00"
    assert transport.read(0) is None  # a minute away on the monotonic clock
    assert transport.remaining == 1


@pytest.mark.parametrize(
    ("line", "message"),
    [
        ('{"t": 0, "dir": "sideways", "hex": "30"}', "dir must be"),
        ('{"t": 0, "dir": "in", "hex": "3g"}', "not a report line"),
        ('{"t": 0, "dir": "in", "hex": ""}', "empty report"),
        ("30 00 00", "not a report line"),
    ],
)
def test_malformed_lines_are_named(line, message):
    with pytest.raises(ControllerError, match=message):
        replay.parse_line(line, "x.jsonl:3")


def test_field_name_aliases_are_read():
    line = '{"timestamp": 0.5, "direction": "IN", "data": "30 08 00"}'
    assert replay.parse_line(line) == replay.Record(0.5, replay.IN, b"\x30\x08\x00")


def test_time_must_not_go_backwards(tmp_path):
    path = tmp_path / "bad.jsonl"
    path.write_text('{"t": 1, "dir": "in", "hex": "30"}\n{"t": 0.5, "dir": "in", "hex": "30"}\n')
    with pytest.raises(ControllerError, match=r"bad\.jsonl:2: time goes backwards"):
        replay.load(path)


def test_recording_round_trips_through_the_format(tmp_path):
    source = replay.ReplayTransport(
        [
            replay.Record(5.0, replay.IN, b"\x30\x00\x08"),
            replay.Record(5.25, replay.IN, b"\x30\x00\x00"),
        ]
    )
    out = io.StringIO()
    recorder = replay.RecordingTransport(source, out)
    assert recorder.read(0) == b"\x30\x00\x08"
    recorder.write(b"\x11\x10")
    recorder.read(0)
    lines = [replay.parse_line(x) for x in out.getvalue().splitlines()]
    assert lines == [
        replay.Record(0.0, replay.IN, b"\x30\x00\x08"),
        replay.Record(0.0, replay.OUT, b"\x11\x10"),
        replay.Record(0.25, replay.IN, b"\x30\x00\x00"),
    ]
    path = tmp_path / "again.jsonl"
    replay.dump(lines, path)
    assert replay.load(path) == lines


@pytest.mark.skipif(not sys.platform.startswith("linux"), reason="hidraw is Linux's")
def test_no_wiimote_here_says_how_to_connect_one():
    # No Wiimote is attached to these machines: the real hidraw enumeration finds none.
    assert hid_transport.find_wiimotes() == []
    with pytest.raises(NoDeviceError, match="pair it over Bluetooth"):
        hid_transport.open_wiimote()


def _sysfs(tmp_path, node: str, driver: str) -> str:
    """A sysfs tree as the kernel lays it out: /sys/class/hidraw/<node>/device → the HID
    device directory, whose driver link names the bound driver."""
    hid_dir = tmp_path / "devices" / "0005:057E:0306.0004"
    (tmp_path / "drivers" / driver).mkdir(parents=True)
    hid_dir.mkdir(parents=True)
    os.symlink(tmp_path / "drivers" / driver, hid_dir / "driver")
    (tmp_path / "class" / "hidraw" / node).mkdir(parents=True)
    os.symlink(hid_dir, tmp_path / "class" / "hidraw" / node / "device")
    return str(tmp_path)


def test_kernel_driver_holding_the_device_is_named_with_the_unbind_command(tmp_path):
    root = _sysfs(tmp_path, "hidraw3", "wiimote")
    with pytest.raises(DriverBusyError) as info:
        hid_transport.check_kernel_driver(b"/dev/hidraw3", root)
    assert "drivers/wiimote/unbind" in str(info.value)
    assert "0005:057E:0306.0004" in str(info.value)
    hid_transport.check_kernel_driver(
        b"/dev/hidraw3", _sysfs(tmp_path / "g", "hidraw3", "hid-generic")
    )


def test_permission_problem_suggests_a_udev_rule(tmp_path):
    denied = OSError(errno.EACCES, "Permission denied")
    err = hid_transport.diagnose_open_failure(b"/dev/hidraw3", denied, str(tmp_path))
    assert isinstance(err, DevicePermissionError)
    assert "udev rule" in str(err) and 'KERNELS=="0005:057E:0306.*"' in str(err)
    other = hid_transport.diagnose_open_failure(b"/dev/hidraw3", OSError("open failed"), "/x")
    assert type(other) is ControllerError and "could not open the Wiimote" in str(other)


def test_an_unwritable_recording_closes_the_device_and_says_so(tmp_path):
    inner = replay.ReplayTransport([replay.Record(0.0, replay.IN, b"\x30\x00\x00")])
    with pytest.raises(ControllerError, match="cannot write the session recording"):
        replay.RecordingTransport(inner, tmp_path / "no such folder" / "s.jsonl")
    with pytest.raises(ControllerDisconnectedError, match="closed"):
        inner.read(0)  # released


class FakeDevice:
    """What ``hidraw.device()`` returns, for the open path (no Wiimote on these machines)."""

    def __init__(self) -> None:
        self.closes = 0

    def open_path(self, path) -> None:
        self.path = path

    def close(self) -> None:
        self.closes += 1


def test_open_wiimote_with_an_unwritable_recording_releases_the_device(tmp_path, monkeypatch):
    device = FakeDevice()
    module = SimpleNamespace(
        enumerate=lambda vid, pid: [{"path": b"/dev/hidraw-test"}] if pid == 0x0306 else [],
        device=lambda: device,
    )
    monkeypatch.setattr(hid_transport, "hid_module", lambda: module)
    monkeypatch.setattr(hid_transport, "check_kernel_driver", lambda path: None)
    with pytest.raises(ControllerError, match="cannot write the session recording"):
        hid_transport.open_wiimote(record_to=tmp_path / "missing" / "s.jsonl")
    assert device.closes == 1
    transport = hid_transport.open_wiimote(record_to=tmp_path / "s.jsonl")
    transport.close()
    transport.close()  # a second close (every way a session ends closes) does nothing more
    assert device.closes == 2 and (tmp_path / "s.jsonl").exists()
