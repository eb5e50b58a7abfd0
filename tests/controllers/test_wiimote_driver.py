"""The driver over the replay transport, fed hand-written report streams (streams.py)."""

from __future__ import annotations

import pytest
from wiimote_streams import (
    ACK_WRITE,
    CALIBRATION_REPLY,
    NUNCHUK_CAL_REPLY,
    NUNCHUK_ID_REPLY,
    NUNCHUK_INIT_OUTPUT,
    START_OUTPUT,
    STATUS_EXTENSION,
    STATUS_NO_EXTENSION,
    pad,
    records,
    report_0x37,
)

from btf_addon.controllers.actions import Action
from btf_addon.controllers.controls import Controls
from btf_addon.controllers.replay import ReplayTransport
from btf_addon.controllers.transport import ControllerDisconnectedError
from btf_addon.controllers.wiimote.buttons import Button
from btf_addon.controllers.wiimote.driver import Wiimote


def written(transport: ReplayTransport) -> list[str]:
    return [r.data.hex() for r in transport.written]


def run(stream, **options) -> tuple[Wiimote, ReplayTransport, list]:
    transport = ReplayTransport(stream)
    wiimote = Wiimote(transport, **options)
    wiimote.start()
    samples = []
    with pytest.raises(ControllerDisconnectedError, match="recording ended"):
        while True:
            samples += wiimote.poll()
    samples += wiimote.pending
    return wiimote, transport, samples


def four_acks(t0: float) -> list[tuple[float, str]]:
    return [(t0 + 0.001 * i, ACK_WRITE) for i in range(4)]


def test_start_sequence_byte_for_byte_and_mode_resent_after_status():
    stream = records(
        (0.00, STATUS_NO_EXTENSION),
        *four_acks(0.01),
        (0.02, CALIBRATION_REPLY),
        (0.03, report_0x37()),
    )
    wiimote, transport, _ = run(stream)
    out = written(transport)
    # Everything of the start, then 0x12 again for the status report (in any position after it).
    assert out[: len(START_OUTPUT)] == START_OUTPUT
    assert out[len(START_OUTPUT) :] == ["120437"]
    assert not [e for e in wiimote.events if e.kind in ("timeout", "error", "unexpected")]


def test_ir_off_and_sensitivity_choice():
    transport = ReplayTransport(records((0.0, STATUS_NO_EXTENSION)))
    Wiimote(transport, ir_enabled=False).start()
    assert written(transport) == ["1110", "1500", "120435", "17000000160008"]
    transport = ReplayTransport(records((0.0, STATUS_NO_EXTENSION)))
    Wiimote(transport, ir_sensitivity=5).start()
    assert written(transport)[5][12:30] == "070000710100720020"  # level 5's block 1


def test_calibration_read_and_applied():
    # Raw x 0x9a (616) with zero 512, one g 616 → exactly 1 g; flat z → roll 90°.
    stream = records(
        (0.00, STATUS_NO_EXTENSION),
        (0.02, CALIBRATION_REPLY),
        (0.03, report_0x37(accel="9a8080")),
    )
    wiimote, _, samples = run(stream)
    assert wiimote.calibrated and wiimote.calibration.zero == (512, 512, 512)
    last = samples[-1]
    assert last.accel_g == pytest.approx((1.0, 0.0, 0.0))
    assert last.tilt_deg == pytest.approx((90.0, 0.0))


def test_ir_dots_decoded_from_0x37():
    stream = records((0.0, CALIBRATION_REPLY), (0.01, report_0x37(ir="23455b6789ffffffffff")))
    _, _, samples = run(stream)
    assert [(d.x, d.y) for d in samples[-1].ir_dots] == [(0x123, 0x145), (0x367, 0x289)]


def test_buttons_in_every_report_kind_with_timestamps():
    stream = records(
        (0.00, "20 0008 10 0000 c8"),  # A in a status report
        (0.10, "30 0100"),  # Left in mode 0x30
        (0.20, "31 0200 808080"),  # Right in 0x31
        (0.30, report_0x37(buttons="0004")),  # B in 0x37
    )
    _, _, samples = run(stream)
    assert [(s.t, s.buttons) for s in samples] == [
        (0.0, Button.A),
        (0.1, Button.LEFT),
        (0.2, Button.RIGHT),
        (0.3, Button.B),
    ]


def test_nunchuk_plugged_in_mid_session_then_removed():
    stream = records(
        (0.00, STATUS_NO_EXTENSION),
        *four_acks(0.005),
        (0.01, CALIBRATION_REPLY),
        (0.10, report_0x37(ext="e08080809a03")),  # no extension yet: these bytes are ignored
        (0.50, STATUS_EXTENSION),  # plugged in
        (0.51, ACK_WRITE),
        (0.52, ACK_WRITE),
        (0.53, NUNCHUK_ID_REPLY),
        (0.54, NUNCHUK_CAL_REPLY),
        (0.60, report_0x37(ext="e0 80 80 80 b3 01")),  # stick full right, C held
        (0.70, "20 0000 10 0000 64"),  # unplugged
        (0.80, report_0x37(ext="e0 80 80 80 b3 01")),
    )
    wiimote, transport, samples = run(stream)
    assert next(s for s in samples if s.t == 0.10).nunchuk is None
    plugged = next(s for s in samples if s.t == 0.60)
    assert plugged.nunchuk.stick == pytest.approx((1.0, 0.0))
    assert plugged.nunchuk.c and not plugged.nunchuk.z and plugged.nunchuk.calibrated
    assert next(s for s in samples if s.t == 0.80).nunchuk is None
    out = written(transport)
    after_status = out[len(START_OUTPUT) + 1 :]  # after the first status's 0x12
    assert after_status[:4] == ["120437", *NUNCHUK_INIT_OUTPUT]
    assert after_status[4] == "1704a400200010"  # Nunchuk calibration, 16 bytes at 0xA40020
    assert after_status[5:] == ["120437"]  # the unplug status report
    kinds = [e.kind for e in wiimote.events]
    assert "extension" in kinds and "extension-removed" in kinds


def test_status_report_interrupting_the_stream_keeps_data_flowing():
    stream = records(
        (0.00, CALIBRATION_REPLY),
        (0.01, report_0x37(buttons="0008")),
        (0.02, STATUS_NO_EXTENSION),
        (0.03, report_0x37(buttons="0008")),
    )
    wiimote, transport, samples = run(stream)
    assert [s.buttons for s in samples] == [0, Button.A, 0, Button.A]
    assert written(transport)[-1] == "120437"  # re-sent at once after the 0x20
    assert wiimote.battery == 1.0


def test_truncated_and_unknown_reports_are_skipped():
    stream = records(
        (0.00, CALIBRATION_REPLY),
        (0.01, "37 0008 80"),  # truncated
        (0.02, "4a 0000"),  # unknown id
        (0.03, "21 0000"),  # truncated read reply
        (0.04, report_0x37(buttons="0008")),
    )
    wiimote, _, samples = run(stream)
    assert [s.t for s in samples] == [0.0, 0.04]
    kinds = [e.kind for e in wiimote.events]
    assert kinds.count("truncated") == 2 and kinds.count("unknown") == 1


def test_read_without_reply_times_out_and_the_queue_moves_on():
    # No calibration reply: after 1 s of report time the read times out (typical values used)
    # and the Nunchuk init queued behind it goes out.
    stream = records(
        (0.00, STATUS_EXTENSION),
        *[(0.1 * i, report_0x37()) for i in range(1, 12)],
    )
    wiimote, transport, _ = run(stream, timeout_s=1.0)
    timeouts = [e for e in wiimote.events if e.kind == "timeout"]
    assert any("calibration" in e.text for e in timeouts)
    assert not wiimote.calibrated
    cal_timeout = next(e.t for e in timeouts if "calibration" in e.text)
    assert cal_timeout == pytest.approx(1.1)  # first report more than 1 s after the read
    out = written(transport)
    assert NUNCHUK_INIT_OUTPUT[0] in out
    assert [r.t for r in transport.written if r.data.hex() == NUNCHUK_INIT_OUTPUT[0]] == [
        pytest.approx(1.1)
    ]


def test_write_error_and_rumble_bit():
    stream = records((0.0, "22 0000 16 04"), (0.01, report_0x37()))
    transport = ReplayTransport(stream)
    wiimote = Wiimote(transport)
    wiimote.start()
    wiimote.poll(max_reports=1)
    assert any(e.kind == "error" for e in wiimote.events)
    wiimote.pulse_rumble(0.005)
    wiimote.send_reporting_mode()
    assert written(transport)[-2:] == ["1111", "120537"]  # rumble rides on bit 0
    with pytest.raises(ControllerDisconnectedError):
        wiimote.poll()  # 0.01 ≥ 0.0 + 0.005 switches it off before the stream ends
    assert written(transport)[-1] == "1110"


def test_reply_before_its_request_is_dropped_and_the_read_answered_by_its_own_reply():
    # Replies the driver has not asked for yet (the identity and Nunchuk calibration while the
    # accelerometer calibration read is in flight) are dropped; the reads sent later are
    # answered only by the replies that follow them.
    stream = records(
        (0.00, STATUS_EXTENSION),
        (0.02, NUNCHUK_ID_REPLY),  # early: dropped
        (0.03, NUNCHUK_CAL_REPLY),  # early too
        (0.05, CALIBRATION_REPLY),  # the calibration read completes, the identity read goes out
        (0.06, report_0x37(ext="e0 80 80 80 b3 03")),
    )
    wiimote, _, samples = run(stream)
    assert wiimote.calibrated and wiimote.extension is None  # the identity read still waits
    assert samples[-1].nunchuk is None
    stream += records(
        (0.07, NUNCHUK_ID_REPLY),
        (0.08, NUNCHUK_CAL_REPLY),
        (0.10, report_0x37(ext="e0 80 80 80 b3 03")),
    )
    wiimote, _, samples = run(stream)
    assert wiimote.extension == "nunchuk"
    assert samples[-1].nunchuk.stick == pytest.approx((1.0, 0.0))
    assert samples[-1].nunchuk.calibrated
    assert not [e for e in wiimote.events if e.kind in ("timeout", "error")]


def test_stray_read_replies_never_answer_a_later_read():
    # Issue 30 item 11: a late error reply at 0x00FA (an identity read long timed out) came
    # before a Nunchuk was plugged in; kept, it failed the new identity read ("unknown", dead
    # stick). A reply at the awaited offset but of another size is not the read's either.
    stream = records(
        (0.00, STATUS_NO_EXTENSION),
        *four_acks(0.005),
        (0.01, CALIBRATION_REPLY),
        (0.10, pad("21 0000 08 00fa", 22)),  # error 8 at 0x00FA: no read in flight
        (0.60, STATUS_EXTENSION),  # plugged in 0.5 s later
        (0.61, ACK_WRITE),
        (0.62, ACK_WRITE),
        (0.625, pad("21 0000 f0 00fa" + "11" * 16, 22)),  # 16 bytes at 0x00FA: not the 6 asked
        (0.63, NUNCHUK_ID_REPLY),
        (0.64, NUNCHUK_CAL_REPLY),
        (0.70, report_0x37(ext="e0 80 80 80 b3 03")),
    )
    wiimote, _, samples = run(stream)
    assert wiimote.extension == "nunchuk"
    assert samples[-1].nunchuk.stick == pytest.approx((1.0, 0.0))
    assert not [e for e in wiimote.events if e.kind in ("timeout", "error")]


def test_error_reply_to_the_read_in_flight_is_reported():
    stream = records(
        (0.00, STATUS_EXTENSION),
        (0.01, CALIBRATION_REPLY),
        (0.02, ACK_WRITE),
        (0.03, ACK_WRITE),
        (0.04, pad("21 0000 08 00fa", 22)),  # the identity read fails
        (0.05, report_0x37()),
    )
    wiimote, transport, _ = run(stream)
    assert wiimote.extension == "unknown"
    assert [e.kind for e in wiimote.events].count("error") == 1
    assert "1704a400200010" not in written(transport)  # no calibration read for an unknown


def test_short_status_report_resends_the_mode_and_gives_its_buttons():
    # Issue 30 item 9: any 0x20, even one cut short, means the Wiimote reset its reporting mode.
    stream = records(
        (0.00, CALIBRATION_REPLY),
        (0.01, report_0x37()),
        (0.02, "20 0008"),  # keys only (A held)
        (0.03, "20"),  # nothing but the id
        (0.04, report_0x37(buttons="0008")),
    )
    wiimote, transport, samples = run(stream)
    assert [(s.t, s.buttons) for s in samples] == [
        (0.0, 0),
        (0.01, 0),
        (0.02, Button.A),
        (0.04, Button.A),
    ]
    resent = [r.t for r in transport.written[len(START_OUTPUT) :]]
    assert written(transport)[len(START_OUTPUT) :] == ["120437", "120437"]
    assert resent == [0.02, 0.03]  # at once, for each
    assert [e.kind for e in wiimote.events].count("truncated") == 2
    assert wiimote.battery is None  # a short report has no battery byte


def test_unplug_status_sample_carries_no_nunchuk_state():
    # Issue 30 item 10: the sample of the unplug status report must not keep C held and the
    # stick deflected until the next data report.
    stream = records(
        (0.00, STATUS_NO_EXTENSION),
        *four_acks(0.005),
        (0.01, CALIBRATION_REPLY),
        (0.50, STATUS_EXTENSION),
        (0.51, ACK_WRITE),
        (0.52, ACK_WRITE),
        (0.53, NUNCHUK_ID_REPLY),
        (0.54, NUNCHUK_CAL_REPLY),
        (0.60, report_0x37(ext="e0 80 80 80 b3 01")),  # stick full right, C held
        (0.70, "20 0000 10 0000 64"),  # unplugged
        (0.71, ACK_WRITE),  # any later non-data report: still no Nunchuk
        (0.80, report_0x37()),
    )
    _, _, samples = run(stream)
    assert next(s for s in samples if s.t == 0.60).nunchuk.c
    assert [s.nunchuk for s in samples if s.t >= 0.70] == [None, None, None]
    controls = Controls()
    edits = controls.step(0.80, samples) + controls.finish(0.80)
    zoom = sum(e.amount for e in edits if e.action is Action.ZOOM_IN)
    orbit = sum(e.amount for e in edits if e.action is Action.ORBIT_CAMERA)
    assert zoom == pytest.approx(0.1)  # C held 0.60 → 0.70 at 1 stop/s
    assert orbit == pytest.approx(6.0)  # full right 0.60 → 0.70 at 60°/s
