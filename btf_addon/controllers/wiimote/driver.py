"""The Wiimote driver: a non-blocking state machine over a transport.

``start()`` writes the connection sequence; ``poll()`` reads whatever reports are waiting and
returns one ``Sample`` per report that carries controller input, each stamped with the
transport's time of that report. Output reports leave in order through one queue. A memory read
holds the queue until its 0x21 replies are in (the replies carry only the low 16 bits of the
address, so one read at a time) or ``timeout_s`` seconds of report time have passed; a write
does not hold it (the Wiimote handles reports in order), and its 0x22 ack is matched in order to
report errors and timeouts. Nothing here sleeps, so a recording replays synchronously and a
timer in Blender never blocks.

Connection sequence (what a recording of this driver shows, in order):
1. 0x11 LEDs (player LED 1: ``11 10``), 2. 0x15 status request (``15 00``), 3. with IR:
``13 04``, ``1a 04`` and the four 0x16 writes of ``ir.ir_memory_writes`` (0x08 → 0x04B00030,
block 1 → 0x04B00000, block 2 → 0x04B0001A, mode → 0x04B00033; basic mode 1 with 0x37),
4. 0x12 ``12 04 37`` (IR on) or ``12 04 35`` (IR off): continuous reporting with accelerometer,
IR and extension bytes, 5. 0x17 read of 8 bytes at EEPROM 0x0016 (accelerometer calibration).
After every 0x20 status report, a truncated one included (the Wiimote resets its reporting mode
whenever it sends one and reports no data until told again; the kernel's hid-wiimote re-sends
the mode for its 2-byte-payload form too), the driver re-sends that 0x12 at once. If no data
report comes for WATCHDOG_S of transport time after ``start()`` (a lost 0x20 would otherwise
silence the Wiimote for good), it re-sends the 0x12 and requests status, at most once per
WATCHDOG_S. When a status report says an extension appeared: write 0x55 to 0x04A400F0, 0x00 to
0x04A400FB, read 6 bytes at 0x04A400FA (identity) and, for a Nunchuk, 16 bytes at 0x04A40020
(calibration). When it says the extension left, the Nunchuk is dropped at once: that status
report's sample and every later one carry no Nunchuk state. A read reply that is not the next
one the read in flight awaits (its offset and size) is dropped, never kept for a later read.
"""

from __future__ import annotations

import logging
from collections import deque
from collections.abc import Callable
from dataclasses import dataclass, field, replace

from . import accel, ir, memory, nunchuk, reports
from .buttons import parse_buttons
from .reports import ReportError

log = logging.getLogger(__name__)

# Data comes at ~100 Hz in continuous mode, so half a second without any is no gap in the stream
# but a Wiimote that lost its reporting mode.
WATCHDOG_S = 0.5


@dataclass(frozen=True)
class NunchukState:
    stick: tuple[float, float] = (0.0, 0.0)  # −1..1, x right, y up
    c: bool = False
    z: bool = False
    accel_g: tuple[float, float, float] = (0.0, 0.0, 1.0)
    calibrated: bool = False


@dataclass(frozen=True)
class Sample:
    """The controller's state after one input report at time ``t`` (seconds)."""

    t: float
    buttons: int  # buttons.Button mask
    accel_g: tuple[float, float, float] | None = None
    tilt_deg: tuple[float, float] | None = None  # (roll, pitch)
    ir_dots: tuple[ir.Dot, ...] = ()
    nunchuk: NunchukState | None = None


@dataclass
class _Operation:
    report: bytes
    wait: str | None  # None, "ack" or "read"
    done: Callable[[bytes | None], None] | None = None
    what: str = ""
    address: int = 0
    size: int = 0
    sent_at: float | None = None
    received: bytearray = field(default_factory=bytearray)


@dataclass
class DriverEvent:
    t: float
    kind: str  # "status", "calibrated", "extension", "extension-removed", "timeout", ...
    text: str


class Wiimote:
    """One Wiimote on a transport. ``ir``: enable the IR camera (sensitivity 1..5)."""

    def __init__(
        self,
        transport,
        *,
        ir_enabled: bool = True,
        ir_sensitivity: int = ir.DEFAULT_SENSITIVITY,
        timeout_s: float = 1.0,
        leds: int = 0b0001,
    ) -> None:
        self.transport = transport
        self.ir_enabled = ir_enabled
        self.ir_sensitivity = ir_sensitivity
        self.timeout_s = timeout_s
        self.leds = leds
        self.rumble = False
        self._rumble_until: float | None = None
        self.mode = 0x37 if ir_enabled else 0x35
        self.calibration = accel.AccelCalibration.default()
        self.calibrated = False
        self.extension: str | None = None  # "nunchuk", another name, "unknown", or None
        self._extension_plugged = False
        self.nunchuk_calibration = nunchuk.NunchukCalibration.default()
        self.battery: float | None = None
        self.events: list[DriverEvent] = []
        self._queue: deque[_Operation] = deque()
        self._writes: deque[_Operation] = deque()  # sent writes awaiting their 0x22 ack
        # Time of the last data report or watchdog request; None until start(): no data expected.
        self._quiet_since: float | None = None
        self._last = Sample(0.0, 0)
        self.pending: list[Sample] = []  # the samples of a poll that ended in a disconnect
        if ir_sensitivity not in ir.SENSITIVITY:
            raise ValueError(f"IR sensitivity must be 1..5, not {ir_sensitivity}")

    # ----------------------------------------------------------------- output
    def _event(self, kind: str, text: str) -> None:
        self.events.append(DriverEvent(self.transport.now(), kind, text))
        log.info("wiimote %s: %s", kind, text)

    def _send(self, report: bytes) -> None:
        data = bytearray(report)
        if len(data) > 1:
            data[1] = (data[1] & 0xFE) | (0x01 if self.rumble else 0x00)
        self.transport.write(bytes(data))

    def _enqueue(self, op: _Operation) -> None:
        self._queue.append(op)
        self._pump()

    def _pump(self) -> None:
        while self._queue and self._queue[0].sent_at is None:
            op = self._queue[0]
            self._send(op.report)
            op.sent_at = self.transport.now()
            if op.wait == "read":
                return
            self._queue.popleft()
            if op.wait == "ack":
                self._writes.append(op)
            elif op.done:
                op.done(b"")

    def write_memory(self, address: int, data: bytes, what: str = "", done=None) -> None:
        """Queue a write; ``done(b"")`` after its ack, ``done(None)`` on error or timeout (later
        output does not wait for the ack)."""
        report = memory.write_request(address, data)
        self._enqueue(_Operation(report, "ack", done, what or f"write {address:#010x}"))

    def read_memory(self, address: int, size: int, what: str = "", done=None) -> None:
        """Queue a read; ``done(data)`` with ``size`` bytes, ``done(None)`` on error/timeout."""
        report = memory.read_request(address, size)
        op = _Operation(report, "read", done, what or f"read {address:#010x}", address, size)
        self._enqueue(op)

    def set_leds(self, leds: int) -> None:
        self.leds = leds & 0x0F
        self._send(reports.leds_report(self.leds))

    def set_rumble(self, on: bool) -> None:
        """Rumble rides on bit 0 of every output report; the LED report carries the change."""
        self.rumble = on
        self._rumble_until = None
        self._send(reports.leds_report(self.leds))

    def pulse_rumble(self, seconds: float = 0.15) -> None:
        """Rumble for ``seconds`` of report time (switched off by a later poll)."""
        self.set_rumble(True)
        self._rumble_until = self.transport.now() + seconds

    def send_reporting_mode(self) -> None:
        self._send(reports.reporting_mode_report(self.mode))

    def start(self) -> None:
        self._quiet_since = self.transport.now()
        self._send(reports.leds_report(self.leds))
        self._send(reports.status_request_report())
        if self.ir_enabled:
            for report in reports.ir_enable_reports():
                self._enqueue(_Operation(report, None, None, "IR enable"))
            mode = ir.MODE_BASIC if self.mode in (0x36, 0x37) else ir.MODE_EXTENDED
            for report in ir.ir_memory_writes(self.ir_sensitivity, mode):
                self._enqueue(_Operation(report, "ack", None, "IR set-up"))
        self._enqueue(_Operation(reports.reporting_mode_report(self.mode), None, None, "mode"))
        self.read_memory(
            accel.CALIBRATION_ADDRESS,
            accel.CALIBRATION_SIZE,
            "accelerometer calibration",
            self._on_calibration,
        )

    # ---------------------------------------------------------------- results
    def _on_calibration(self, data: bytes | None) -> None:
        cal = accel.parse_calibration(data) if data else None
        if cal is None:
            self._event("calibration", "accelerometer calibration unusable: typical values used")
            return
        self.calibration, self.calibrated = cal, True
        self._event("calibrated", f"accelerometer zero {cal.zero}, one g {cal.one_g}")

    def _plug_extension(self) -> None:
        self._extension_plugged = True
        self.extension = None
        (a0, v0), (a1, v1) = nunchuk.INIT_WRITES
        self.write_memory(a0, bytes((v0,)), "extension init 1")
        self.write_memory(a1, bytes((v1,)), "extension init 2")
        self.read_memory(nunchuk.ID_ADDRESS, nunchuk.ID_SIZE, "extension id", self._on_identity)

    def _on_identity(self, data: bytes | None) -> None:
        if not self._extension_plugged:
            return
        if data is None:
            self.extension = "unknown"
            self._event("extension", "extension present but its identity could not be read")
            return
        self.extension = nunchuk.EXTENSION_NAMES.get(bytes(data), "unknown")
        self._event("extension", f"{self.extension} ({bytes(data).hex()})")
        if self.extension == "nunchuk":
            self.nunchuk_calibration = nunchuk.NunchukCalibration.default()
            self.read_memory(
                nunchuk.CALIBRATION_ADDRESS,
                nunchuk.CALIBRATION_SIZE,
                "Nunchuk calibration",
                self._on_nunchuk_calibration,
            )

    def _on_nunchuk_calibration(self, data: bytes | None) -> None:
        cal = nunchuk.parse_nunchuk_calibration(data) if data else None
        if cal is None:
            self._event("calibration", "Nunchuk calibration unusable: typical values used")
            return
        self.nunchuk_calibration = cal
        self._event("calibrated", f"Nunchuk stick {cal.stick}")

    def _finish(self, op: _Operation, result: bytes | None) -> None:
        self._queue.popleft()
        if op.done:
            op.done(result)
        self._pump()

    def check_timeouts(self) -> None:
        now = self.transport.now()
        if self._rumble_until is not None and now >= self._rumble_until:
            self.set_rumble(False)
        while self._writes and now - self._writes[0].sent_at > self.timeout_s:
            op = self._writes.popleft()
            self._event("timeout", f"no ack for {op.what} within {self.timeout_s} s")
            if op.done:
                op.done(None)
        if self._queue and self._queue[0].sent_at is not None:
            op = self._queue[0]
            if now - op.sent_at > self.timeout_s:
                self._event("timeout", f"no reply to {op.what} within {self.timeout_s} s")
                self._finish(op, None)

    def check_watchdog(self) -> None:
        """Re-send the reporting mode and request status when no data report has come for
        WATCHDOG_S since the last data report or the last such request (so at most once per
        WATCHDOG_S however often it is called)."""
        if self._quiet_since is None:
            return
        now = self.transport.now()
        if now - self._quiet_since < WATCHDOG_S:
            return
        self._quiet_since = now
        self._event(
            "watchdog", f"no data report for {WATCHDOG_S} s: reporting mode re-sent, status asked"
        )
        self.send_reporting_mode()
        self._send(reports.status_request_report())

    # ------------------------------------------------------------------ input
    def handle(self, report: bytes) -> Sample | None:
        """Process one input report (at the transport's ``now()``); a Sample when it carried
        controller input, None otherwise. Unknown and truncated reports are logged and
        skipped, never raised."""
        t = self.transport.now()
        if not report:
            return None
        rid = report[0]
        need = reports.INPUT_LENGTHS.get(rid)
        if need is None:
            self._event("unknown", f"unknown report id {rid:#04x} ignored")
            return None
        if rid in reports.DATA_MODES and self._quiet_since is not None:
            self._quiet_since = t  # even a truncated one: the Wiimote is reporting
        if len(report) < (6 if rid == reports.READ_REPLY else need):
            if rid != reports.STATUS:
                self._event("truncated", f"report {rid:#04x} with {len(report)} bytes ignored")
                return None
            sample = self._short_status(t, report)
        else:
            try:
                sample = self._dispatch(t, rid, report)
            except (ReportError, ValueError) as exc:
                self._event("truncated", f"report {rid:#04x}: {exc}")
                return None
        self.check_timeouts()
        if sample is not None:
            self._last = sample
        return sample

    def _short_status(self, t: float, report: bytes) -> Sample | None:
        """A truncated 0x20 still reset the Wiimote's reporting mode; its flags and battery are
        missing, so the extension state stays as it was."""
        self._event("truncated", f"status report with {len(report)} bytes: reporting mode re-sent")
        self.send_reporting_mode()
        if len(report) < 3:
            return None
        return replace(self._last, t=t, buttons=parse_buttons(report[1:3]))

    def _dispatch(self, t: float, rid: int, report: bytes) -> Sample | None:
        payload = report[1:]
        if rid == reports.STATUS:
            status = reports.parse_status(report)
            self.battery = status.battery
            self._event("status", f"battery {status.battery:.0%}, extension {status.extension}")
            self.send_reporting_mode()
            if status.extension and not self._extension_plugged:
                self._plug_extension()
            elif not status.extension and self._extension_plugged:
                self._extension_plugged = False
                self.extension = None
                self._event("extension-removed", "the extension was unplugged")
            # Until the next data report, samples are built from this one: a Nunchuk state kept
            # here would hold a released C/Z or stick after the Nunchuk is gone.
            nunchuk_state = self._last.nunchuk if self.extension == "nunchuk" else None
            return replace(self._last, t=t, buttons=status.buttons, nunchuk=nunchuk_state)
        if rid == reports.ACK:
            ack = reports.parse_ack(report)
            if ack.report == memory.WRITE_MEMORY and self._writes:
                op = self._writes.popleft()
                if ack.error:
                    self._event("error", f"{op.what} failed with error {ack.error}")
                if op.done:
                    op.done(None if ack.error else b"")
            elif ack.error:
                self._event("error", f"report {ack.report:#04x} failed with error {ack.error}")
            return replace(self._last, t=t, buttons=ack.buttons)
        if rid == reports.READ_REPLY:
            reply = memory.parse_read_reply(report)
            self._on_read_reply(reply)
            return replace(self._last, t=t, buttons=reply.buttons)
        return self._data_report(t, rid, payload)

    def _on_read_reply(self, reply: memory.ReadReply) -> None:
        """Match a 0x21 to the read in flight: the next chunk it awaits, by offset and size (an
        error reply by offset: its size field says nothing). Anything else (the late reply to a
        read that timed out, a reply in another address space with the same low 16 bits) is
        dropped: replies carry only 16 address bits and no request id, so one kept for later
        could answer a different read, as a late error at 0x00FA once failed the identity of a
        Nunchuk plugged in afterwards."""
        head = self._queue[0] if self._queue else None
        if head is not None and head.wait == "read" and head.sent_at is not None:
            expected = (head.address + len(head.received)) & 0xFFFF
            chunk = min(16, head.size - len(head.received))
            if reply.offset == expected and (reply.error or len(reply.data) == chunk):
                if reply.error:
                    self._event("error", f"{head.what} failed with error {reply.error}")
                    self._finish(head, None)
                    return
                head.received += reply.data
                if len(head.received) >= head.size:
                    self._finish(head, bytes(head.received[: head.size]))
                return
        log.debug(
            "wiimote: read reply at %#06x (%d bytes, error %d) matches no read in flight: dropped",
            reply.offset,
            len(reply.data),
            reply.error,
        )

    def _data_report(self, t: float, rid: int, payload: bytes) -> Sample:
        if rid == 0x3D:  # extension bytes only
            return replace(self._last, t=t, nunchuk=self._nunchuk(payload[0:6]))
        buttons = parse_buttons(payload[0:2])
        sample = Sample(t, buttons, nunchuk=self._last.nunchuk if self.extension else None)
        if rid in (0x31, 0x33, 0x35, 0x37):
            g = accel.to_g(accel.parse_accel(payload[0:5]), self.calibration)
            sample = replace(sample, accel_g=g, tilt_deg=accel.tilt_deg(g))
        if rid == 0x33:
            sample = replace(sample, ir_dots=tuple(ir.parse_extended(payload[5:17])))
        elif rid == 0x36:
            sample = replace(sample, ir_dots=tuple(ir.parse_basic(payload[2:12])))
        elif rid == 0x37:
            sample = replace(sample, ir_dots=tuple(ir.parse_basic(payload[5:15])))
        ext_at = {0x32: 2, 0x34: 2, 0x35: 5, 0x36: 12, 0x37: 15}.get(rid)
        if ext_at is not None:
            sample = replace(sample, nunchuk=self._nunchuk(payload[ext_at : ext_at + 6]))
        return sample

    def _nunchuk(self, data: bytes) -> NunchukState | None:
        if self.extension != "nunchuk":
            return None
        raw = nunchuk.parse_nunchuk(data)
        cal = self.nunchuk_calibration
        return NunchukState(
            stick=(
                nunchuk.stick_value(raw.stick_raw[0], cal.stick.x),
                nunchuk.stick_value(raw.stick_raw[1], cal.stick.y),
            ),
            c=raw.c,
            z=raw.z,
            accel_g=accel.to_g(raw.accel_raw, cal.accel),
            calibrated=cal.stick != nunchuk.StickCalibration.default(),
        )

    def poll(self, max_reports: int = 256, timeout_s: float = 0.0) -> list[Sample]:
        """Read and handle every waiting report (at most ``max_reports``); the first read waits
        up to ``timeout_s``. Raises ControllerDisconnectedError when the device or recording ends
        (the samples read so far are kept in ``self.pending``)."""
        samples: list[Sample] = []
        self.pending = samples
        for i in range(max_reports):
            report = self.transport.read(timeout_s if i == 0 else 0.0)
            if report is None:
                # Only a read that found nothing can tell silence; a replayed recording's gaps
                # between reports it does return are not.
                self.check_timeouts()
                self.check_watchdog()
                break
            sample = self.handle(report)
            if sample is not None:
                samples.append(sample)
        return samples
