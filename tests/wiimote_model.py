"""A scripted Wiimote: a transport that answers like the device does, written from the protocol
description (DESIGN.md "Controllers and headsets", docs/controllers.md), for end-to-end tests
whose replies must follow the driver's actual requests (a recording cannot: its replies sit at
fixed times). It keeps a memory map (EEPROM calibration, IR and extension registers), acks
writes, answers reads (error 8 where nothing is mapped), sends a status report on 0x15 and on
extension hot-plug, and data reports in the mode last set with 0x12, at 100 Hz, from a script
of button states. Like the device (WiiBrew, "Status Reporting"), it forgets its reporting mode
whenever it sends a status report and sends no data until the next 0x12; a read that finds
nothing to send returns None and still advances time by one report interval. Time is
simulated: ``read`` advances it, nothing sleeps.

Faults: ``short_status_at_s`` sends a truncated status report (id and buttons only) at that
time; ``lose_mode_at_s`` forgets the mode with no report at all (its status report lost);
``deaf_from_s`` ignores every output report from then on."""

from __future__ import annotations

from collections import deque

EEPROM_CALIBRATION = bytes.fromhex("80808000 9a9a9a00".replace(" ", ""))  # zero 512, 1 g 616
NUNCHUK_ID = bytes.fromhex("0000a4200000")
NUNCHUK_CAL = bytes.fromhex("80808000b3b3b300e02080e020800000")


class WiimoteModel:
    def __init__(
        self,
        script,
        *,
        end_s: float,
        nunchuk_at_s: float | None = None,
        unplug_at_s: float | None = None,
        short_status_at_s: float | None = None,
        lose_mode_at_s: float | None = None,
        deaf_from_s: float | None = None,
    ) -> None:
        """``script``: [(t, buttons_hex, stick_xy_bytes or None)], the state from t on."""
        self.script = sorted(script)
        self.end_s = end_s
        self.nunchuk_at_s = nunchuk_at_s
        self.unplug_at_s = unplug_at_s
        self.short_status_at_s = short_status_at_s
        self.lose_mode_at_s = lose_mode_at_s
        self.deaf_from_s = deaf_from_s
        self.t = 0.0
        self.next_data_t = 0.01
        self.mode: int | None = None
        self.leds = 0
        self.registers: dict[int, int] = {}
        self.nunchuk_plugged = False
        self.nunchuk_ready = False  # after 0x55 → A400F0 and 0x00 → A400FB
        self.outbox: deque[bytes] = deque()
        self.written: list[bytes] = []

    # ----------------------------------------------------------- state at t
    def _state(self) -> tuple[str, bytes | None]:
        buttons, stick = "0000", None
        for t, b, s in self.script:
            if t <= self.t:
                buttons, stick = b, s
        return buttons, stick

    def _buttons(self) -> bytes:
        return bytes.fromhex(self._state()[0])

    def _status(self) -> bytes:
        flags = (0x02 if self.nunchuk_plugged else 0) | (self.leds << 4)
        return bytes((0x20,)) + self._buttons() + bytes((flags, 0, 0, 0xC8))

    def _memory(self, address: int, size: int) -> bytes | None:
        if address & 0x04000000 == 0:  # EEPROM
            if 0x16 <= address and address + size <= 0x16 + len(EEPROM_CALIBRATION):
                return EEPROM_CALIBRATION[address - 0x16 : address - 0x16 + size]
            return None
        if not (self.nunchuk_plugged and self.nunchuk_ready):
            return None
        reg = address & 0xFFFFFF
        if reg == 0xA400FA and size <= 6:
            return NUNCHUK_ID[:size]
        if reg == 0xA40020 and size <= 16:
            return NUNCHUK_CAL[:size]
        return None

    # -------------------------------------------------------------- transport
    def write(self, data: bytes) -> None:
        self.written.append(bytes(data))
        if self.deaf_from_s is not None and self.t >= self.deaf_from_s:
            return
        rid = data[0]
        if rid == 0x11:
            self.leds = data[1] >> 4
        elif rid == 0x12:
            self.mode = data[2]
        elif rid == 0x15:
            self.outbox.append(self._status())
        elif rid == 0x16:
            address = int.from_bytes(data[1:5], "big") & ~0x01000000  # drop the rumble bit
            size = data[5]
            for i in range(size):
                self.registers[(address & 0xFFFFFF) + i] = data[6 + i]
            if self.registers.get(0xA400F0) == 0x55 and self.registers.get(0xA400FB) == 0x00:
                self.nunchuk_ready = self.nunchuk_plugged
            self.outbox.append(bytes((0x22,)) + self._buttons() + bytes((0x16, 0)))
        elif rid == 0x17:
            address = int.from_bytes(data[1:5], "big") & ~0x01000000
            size = int.from_bytes(data[5:7], "big")
            payload = self._memory(address, size)
            low = (address & 0xFFFF).to_bytes(2, "big")
            if payload is None:
                self.outbox.append(
                    bytes((0x21,)) + self._buttons() + bytes((0x08,)) + low + bytes(16)
                )
            else:
                se = ((len(payload) - 1) << 4).to_bytes(1, "big")
                self.outbox.append(
                    bytes((0x21,)) + self._buttons() + se + low + payload.ljust(16, b"\0")
                )

    def _next_slot(self) -> None:
        """The next report interval (a status report takes a data report's place)."""
        self.t = self.next_data_t
        self.next_data_t = round(self.next_data_t + 0.01, 6)

    def _send_status(self, report: bytes) -> bytes:
        self.mode = None  # the device's reset on every status report
        return report

    def read(self, timeout_s: float) -> bytes | None:
        if self.outbox:
            self.t += 0.001
            report = self.outbox.popleft()
            return self._send_status(report) if report[0] == 0x20 else report
        if self.nunchuk_at_s is not None and not self.nunchuk_plugged:
            if self.next_data_t >= self.nunchuk_at_s:
                self.nunchuk_plugged = True
                self.nunchuk_at_s = None
                self._next_slot()
                return self._send_status(self._status())  # a hot-plug is reported with 0x20
        if self.unplug_at_s is not None and self.nunchuk_plugged:
            if self.next_data_t >= self.unplug_at_s:
                self.nunchuk_plugged = self.nunchuk_ready = False
                self.unplug_at_s = None
                self._next_slot()
                return self._send_status(self._status())
        if self.short_status_at_s is not None and self.next_data_t >= self.short_status_at_s:
            self.short_status_at_s = None
            self._next_slot()
            return self._send_status(bytes((0x20,)) + self._buttons())
        if self.lose_mode_at_s is not None and self.next_data_t >= self.lose_mode_at_s:
            self.lose_mode_at_s = None
            self.mode = None
        if self.next_data_t > self.end_s:
            from btf_addon.controllers.transport import ControllerDisconnectedError

            raise ControllerDisconnectedError("the model's script ended")
        self._next_slot()
        if self.mode is None:
            return None
        if self.mode != 0x37:
            return bytes((0x30,)) + self._buttons()
        _, stick = self._state()
        ext = bytes(6)
        if self.nunchuk_ready:
            ext = (stick or bytes((0x80, 0x80))) + bytes((0x80, 0x80, 0xB3, 0x03))
        return bytes((0x37,)) + self._buttons() + bytes((0x80, 0x80, 0x9A)) + b"\xff" * 10 + ext

    def now(self) -> float:
        return self.t

    def close(self) -> None:
        pass
