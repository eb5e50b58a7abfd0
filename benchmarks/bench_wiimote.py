"""Wiimote operator: input-to-edit latency and the CPU cost of polling at 100 Hz.

Latency: a recorded session (hand-written reports, 100 Hz) replayed through the operator's
session one report per step, as the live timer polls: from the moment the transport returns a
report to the moment the scene property it changes has been written (material slot, exposure,
environment Mapping rotation). The live operator adds the wait for its next timer tick (up to
10 ms, 5 ms on average), which depends on Blender's event loop and is not measured here.

Polling cost: the same session replayed in real time with a poll every 10 ms, process CPU time
over wall time, beside the same 10 ms sleep loop with no polling (the timer's own cost) and
the bpy-free part alone (driver + step function, no scene edits).
"""

from __future__ import annotations

import statistics
import time

from common import table
from wiimote_streams import ACK_WRITE, CALIBRATION_REPLY, STATUS_NO_EXTENSION, records, report_0x37

from btf_addon.controllers.controls import Controls
from btf_addon.controllers.replay import ReplayTransport
from btf_addon.controllers.wiimote.driver import Wiimote

RATE_HZ = 100
SECONDS = 6.0


def session_stream(seconds: float = SECONDS):
    """Every second: Right (next material) pressed for 0.1 s, Plus for 0.1 s, then B + Right
    held 0.5 s (environment rotation); otherwise idle reports at 100 Hz."""
    start = [(0.0, STATUS_NO_EXTENSION), *[(0.001 * (i + 1), ACK_WRITE) for i in range(4)]]
    start.append((0.01, CALIBRATION_REPLY))
    timed = []
    for k in range(round(seconds * RATE_HZ)):
        t = 0.02 + k / RATE_HZ
        phase = (k % RATE_HZ) / RATE_HZ
        buttons = "0000"
        if 0.1 <= phase < 0.2:
            buttons = "0200"  # Right
        elif 0.3 <= phase < 0.4:
            buttons = "1000"  # Plus
        elif 0.5 <= phase < 1.0:
            buttons = "0204"  # B + Right
        timed.append((t, report_0x37(buttons=buttons)))
    return records(*start, *timed)


class ClockedTransport:
    """A transport wrapper that notes the perf_counter at which each report was handed over."""

    def __init__(self, inner) -> None:
        self.inner = inner
        self.read_at = 0.0

    def read(self, timeout_s):
        data = self.inner.read(timeout_s)
        if data is not None:
            self.read_at = time.perf_counter()
        return data

    def write(self, data):
        self.inner.write(data)

    def now(self):
        return self.inner.now()

    def close(self):
        self.inner.close()


def build_scene(bpy):
    scene = bpy.context.scene
    mesh = bpy.data.meshes.new("Cube")
    mesh.from_pydata([(0, 0, 0), (1, 0, 0), (0, 1, 0)], [], [(0, 1, 2)])
    cube = bpy.data.objects.new("Cube", mesh)
    scene.collection.objects.link(cube)
    for name in ("BTF A", "BTF B"):
        mat = bpy.data.materials.new(name)
        mat.btf.enabled = True
    mesh.materials.append(bpy.data.materials["BTF A"])
    bpy.context.view_layer.objects.active = cube
    world = bpy.data.worlds.new("W")
    nodes, links = world.node_tree.nodes, world.node_tree.links
    texture = nodes.new("ShaderNodeTexEnvironment")
    mapping = nodes.new("ShaderNodeMapping")
    links.new(mapping.outputs["Vector"], texture.inputs["Vector"])
    links.new(texture.outputs["Color"], nodes["Background"].inputs["Color"])
    scene.world = world


def latency_rows(bpy, session_module, edits_module) -> list[list]:
    bpy.ops.wm.read_homefile(use_empty=True, use_factory_startup=True)
    build_scene(bpy)
    transport = ClockedTransport(ReplayTransport(session_stream()))
    ctx = edits_module.EditContext(bpy.context.scene, bpy.context.view_layer)
    session = session_module.WiimoteSession(transport, ctx, push_undo=False)
    session.start()
    by_kind: dict[str, list[float]] = {"discrete": [], "continuous": []}
    while True:
        applied = len(session.applied)
        alive = session.step(max_reports=1)
        done = time.perf_counter()
        for edit, _ in session.applied[applied:]:
            by_kind["continuous" if edit.continuous else "discrete"].append(
                done - transport.read_at
            )
        if not alive:
            break
    rows = []
    for kind, values in by_kind.items():
        ms = sorted(v * 1e3 for v in values)
        rows.append([kind, len(ms), statistics.median(ms), ms[int(0.95 * (len(ms) - 1))], ms[-1]])
    return rows


def cpu_at_100hz(step, seconds: float) -> tuple[float, float]:
    """(CPU time ÷ wall time, mean CPU ms per poll) of calling ``step`` every 10 ms."""
    period = 1.0 / RATE_HZ
    polls = round(seconds * RATE_HZ)
    wall0, cpu0 = time.perf_counter(), time.process_time()
    for i in range(polls):
        step()
        delay = wall0 + (i + 1) * period - time.perf_counter()
        if delay > 0:
            time.sleep(delay)
    wall, cpu = time.perf_counter() - wall0, time.process_time() - cpu0
    return cpu / wall, cpu / polls * 1e3


def bpy_free_polling_rows(seconds: float = 3.0) -> list[list]:
    """Measured before bpy is imported: Blender's own threads then cost nothing here."""
    rows = []
    share, per_poll = cpu_at_100hz(lambda: None, seconds)
    rows.append(["10 ms sleep loop alone (baseline), no bpy", share * 100, per_poll])
    wiimote = Wiimote(ReplayTransport(session_stream(seconds + 1), realtime=True))
    controls = Controls()
    wiimote.start()

    def bpy_free():
        controls.step(wiimote.transport.now(), wiimote.poll())

    share, per_poll = cpu_at_100hz(bpy_free, seconds)
    rows.append(["driver + step function (no scene edits), no bpy", share * 100, per_poll])
    return rows


def blender_polling_rows(bpy, session_module, edits_module, seconds: float = 3.0) -> list[list]:
    """In the Blender process (its threads count too): the bare loop and the whole session."""
    rows = []
    share, per_poll = cpu_at_100hz(lambda: None, seconds)
    rows.append(["10 ms sleep loop alone, bpy loaded", share * 100, per_poll])
    bpy.ops.wm.read_homefile(use_empty=True, use_factory_startup=True)
    build_scene(bpy)
    ctx = edits_module.EditContext(bpy.context.scene, bpy.context.view_layer)
    transport = ReplayTransport(session_stream(seconds + 1), realtime=True)
    session = session_module.WiimoteSession(transport, ctx, push_undo=False)
    session.start()
    share, per_poll = cpu_at_100hz(session.step, seconds)
    rows.append(["operator session (driver, step, scene edits)", share * 100, per_poll])
    return rows


def main() -> str:
    polling = bpy_free_polling_rows()

    import bpy

    import btf_addon
    from btf_addon.blender.wiimote import edits as wiimote_edits
    from btf_addon.blender.wiimote import session as wiimote_session

    btf_addon.register()
    try:
        latency = latency_rows(bpy, wiimote_session, wiimote_edits)
        polling += blender_polling_rows(bpy, wiimote_session, wiimote_edits)
        out = [
            table(["edits", "count", "median ms", "p95 ms", "max ms"], latency),
            "",
            table(["polling at 100 Hz", "CPU %", "CPU ms per poll"], polling),
        ]
        return "\n".join(out)
    finally:
        btf_addon.unregister()


if __name__ == "__main__":
    print(main())
