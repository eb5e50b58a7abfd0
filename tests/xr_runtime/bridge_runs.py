"""Many XTAL bridge runs in one bpy-free process, each stopped by a real SIGINT at a random
point, for tests/xr/test_bridge_interrupts.py (issue 30 items 1, 2 and 8).

``python tests/xr_runtime/bridge_runs.py --runs N --seed S --capture-root DIR`` runs the
bridge (``xr/bridge.py`` ``run_bridge``) N times against the runtime that ``XR_RUNTIME_JSON``
names (the test runtime, its script in ``BTF_XR_TEST_SCRIPT``). Each run goes through the
CLI's own interrupt handling (``cli/main.py``: its SIGINT/SIGTERM handlers, installed per run,
and ``raise_if_interrupted`` as the stop check) and is stopped by a SIGINT that a helper thread
sends to this process: for about a quarter of the runs at a random time from the run's start
(start-up, the session's creation), for the others at a random time after its first submitted
frame (the frame loop: waiting, drawing into an acquired swapchain image, submitting,
capturing), now and then followed by a second SIGINT a few milliseconds later (a double
Ctrl-C, landing in the teardown). Runs have no frame limit, so only the signal ends them: a
run that ends otherwise is a failure.

Per run one JSON line on stdout: ``run``, ``code`` (130 for KeyboardInterrupt at the
CLI-like boundary, a BridgeError's exit code, 1 for anything else), ``armed`` ("start" or
"frame"), ``delay_s``, ``signals`` (SIGINTs sent), ``frames`` (submitted), ``capture``
(``ok`` or what is wrong with the capture folder), ``error`` (the exception's text for codes
other than 130), ``first_frame_s``. A run whose SIGINT was lost hangs; the watchdog then ends
the run with code 124 (``lost``). The process exits with the last run's code (130 when all
went well), so the parent sees a real exit status; a crash (a segfault, an abort in the
runtime's strict teardown checks) is a negative status.

Only numpy, moderngl, pyopenxr and btf_addon's bpy-free packages are imported.
"""

from __future__ import annotations

import argparse
import ctypes
import json
import os
import signal
import sys
import threading
import time
import traceback
from pathlib import Path

import numpy as np

ROOT = Path(__file__).resolve().parents[2]
if str(ROOT) not in sys.path:
    sys.path.insert(0, str(ROOT))

from btf_addon.cli import main as cli_main  # noqa: E402
from btf_addon.core.codecs.analytic import GGXBTF, LambertianBTF  # noqa: E402
from btf_addon.core.sampling.envmap import Environment  # noqa: E402
from btf_addon.render.settings import RenderSettings  # noqa: E402
from btf_addon.scene.primitives import plane, uv_sphere  # noqa: E402
from btf_addon.scene.scene import Camera, Material, Scene, look_at  # noqa: E402
from btf_addon.xr.bridge import BridgeError, BridgeSettings, XRBridge, run_bridge  # noqa: E402

CAMERA_AT = np.array([0.0, -4.0, 0.3])
LOST_AFTER_S = 5.0  # a run still going this long after its SIGINT lost it
EYES = ("left", "right")


def scene(rng: np.random.Generator) -> Scene:
    """tests/xr/test_bridge.py's small scene: a GGX sphere on a Lambertian floor."""
    floor = plane(6.0, uv_repeats=3.0, material=1)
    floor.world_from_object = np.eye(4)
    floor.world_from_object[2, 3] = -1.0
    return Scene(
        [uv_sphere(1.0, segments=24, rings=12), floor],
        [Material(GGXBTF((0.9, 0.6, 0.3), 0.35)), Material(LambertianBTF(0.5))],
        Camera(
            look_at(CAMERA_AT, CAMERA_AT + np.array([0.0, 1.0, 0.0])),
            clip_start=0.05,
            clip_end=50.0,
        ),
        Environment(rng.gamma(0.7, 1.0, size=(16, 32, 3))),
    )


def capture_state(directory: Path) -> str:
    """``ok`` when every capture frame has both eyes' EXR and JSON and nothing else is
    there (no staged or temporary files); else what is wrong."""
    if not directory.is_dir():
        return "ok"
    frames: dict[str, set[str]] = {}
    for path in directory.iterdir():
        name = path.name
        if name.startswith("."):
            return f"stray file {name}"
        stem, _, ext = name.rpartition(".")
        frame, _, eye = stem.rpartition("_")
        if not frame.startswith("frame_") or eye not in EYES or ext not in ("exr", "json"):
            return f"unexpected file {name}"
        frames.setdefault(frame, set()).add(f"{eye}.{ext}")
    whole = {f"{eye}.{ext}" for eye in EYES for ext in ("exr", "json")}
    for frame, files in sorted(frames.items()):
        if files != whole:
            return f"{frame} is partial: {sorted(files)}"
    return "ok"


class Interrupter:
    """Sends this process ``count`` SIGINTs: the first ``delay_s`` after ``arm``, the others
    ``gap_s`` apart. ``sent``: how many went out. A watchdog: once a signal went out (here or
    by ``swallowed_sigint``), a run not ``finished`` within ``LOST_AFTER_S`` lost it: the
    process says so and ends with 124 (only a hang can follow a lost interrupt here)."""

    def __init__(self, index: int, delay_s: float, count: int, gap_s: float):
        self.index = index
        self.delay_s, self.count, self.gap_s = delay_s, count, gap_s
        self.sent = 0
        self.armed_at: float | None = None
        self.finished = threading.Event()
        self._cancel = threading.Event()
        self._thread = threading.Thread(target=self._run, daemon=True)
        self._watchdog: threading.Thread | None = None

    def arm(self) -> None:
        if self.armed_at is None:
            self.armed_at = time.monotonic()
            self._thread.start()

    def _run(self) -> None:
        if self._cancel.wait(self.delay_s):
            return
        for i in range(self.count):
            if i and self._cancel.wait(self.gap_s):
                return
            self.signal()

    def signal(self) -> None:
        """One SIGINT to this process, now; the watchdog starts with the first (before the
        signal: its KeyboardInterrupt may be raised here)."""
        self.sent += 1
        if self._watchdog is None:
            self._watchdog = threading.Thread(target=self._watch, daemon=True)
            self._watchdog.start()
        os.kill(os.getpid(), signal.SIGINT)

    def _watch(self) -> None:
        if self.finished.wait(LOST_AFTER_S):
            return
        line = {"run": self.index, "code": 124, "error": "the SIGINT was lost: the run went on"}
        print(json.dumps(line), flush=True)
        os._exit(124)

    def settle(self) -> None:
        """Wait until no more signals come; a KeyboardInterrupt meanwhile is the late one."""
        self._cancel.set()
        while self.armed_at is not None:
            try:
                self._thread.join()
                time.sleep(0.002)  # a handler pending after the last kill runs here
                return
            except KeyboardInterrupt:
                continue


_COMPARE = ctypes.CFUNCTYPE(ctypes.c_int, ctypes.c_void_p, ctypes.c_void_p)


def swallowed_sigint(interrupter: Interrupter) -> None:
    """A SIGINT that lands inside a C library's call back into Python (libc ``qsort`` with a
    Python comparator, as a driver or runtime callback would be): the KeyboardInterrupt is
    raised in the callback, where ctypes prints it and goes on ("Exception ignored on calling
    ctypes callback function"). Only the CLI's record of the signal (cli/main.py
    ``signals_received``, re-raised by ``raise_if_interrupted``) still stops the run: the
    lost-interrupt case of issue 30 item 2."""

    def compare(_a, _b) -> int:
        interrupter.signal()
        time.sleep(0.005)  # the handler runs here, inside the callback
        return 0

    libc = ctypes.CDLL(None)
    items = (ctypes.c_int * 2)(1, 2)
    libc.qsort(items, 2, ctypes.sizeof(ctypes.c_int), _COMPARE(compare))


def run_once(the_scene, settings, interrupter, armed, stop_check, record) -> int:
    """One run under the CLI's boundary: its exit code (``error`` in ``record``)."""
    try:
        if armed == "start":
            interrupter.arm()
        run_bridge(the_scene, RenderSettings(), settings, frames=None, stop_check=stop_check)
        interrupter.settle()
        record["error"] = "the run ended without its SIGINT"
        return 0
    except KeyboardInterrupt:
        return cli_main.EXIT_INTERRUPTED
    except BridgeError as exc:
        record["error"] = f"{type(exc).__name__}: {exc}"
        return exc.exit_code
    except Exception as exc:
        record["error"] = f"{type(exc).__name__}: {exc}"
        traceback.print_exc()
        return 1


def one_run(index: int, rng: np.random.Generator, args, the_scene: Scene) -> dict:
    capture = Path(args.capture_root) / f"run_{index:04d}"
    draw = rng.random()
    armed = "start" if draw < 0.2 else "swallowed" if draw < 0.2 + args.swallowed else "frame"
    delay = float(rng.uniform(0.0, args.start_window if armed == "start" else args.frame_window))
    count = 2 if rng.random() < 0.2 else 1
    interrupter = Interrupter(index, delay, count, float(rng.uniform(0.0, 0.03)))
    settings = BridgeSettings(
        lights_total=int(rng.choice([16, 64, 256])),
        show_hud=bool(rng.random() < 0.5),
        capture_dir=capture if rng.random() < 0.5 else None,
    )
    record = {"run": index, "armed": armed, "delay_s": round(delay, 4), "error": ""}
    frames = [0]
    started = time.monotonic()
    first_frame = [None]
    swallow_at = int(rng.integers(1, 4))  # the frame whose drawing calls back

    def stop_check() -> None:
        frames[0] += 1
        if first_frame[0] is None:
            first_frame[0] = time.monotonic() - started
            if armed == "frame":
                interrupter.arm()
        if not args.no_stop_check:
            cli_main.raise_if_interrupted()

    real_draw_eye = XRBridge._draw_eye

    def draw_eye(bridge, index, *rest):
        if armed == "swallowed" and frames[0] == swallow_at and index == 1 and not interrupter.sent:
            swallowed_sigint(interrupter)
        return real_draw_eye(bridge, index, *rest)

    XRBridge._draw_eye = draw_eye
    previous = cli_main._install_sigterm()  # the CLI's handlers, as `bridge` runs under them
    code = None
    try:
        while True:  # a second SIGINT may land anywhere here, even in an except clause
            try:
                if code is None:
                    code = run_once(the_scene, settings, interrupter, armed, stop_check, record)
                interrupter.settle()
                break
            except KeyboardInterrupt:
                code = cli_main.EXIT_INTERRUPTED if code is None else code
    finally:
        interrupter.finished.set()
        cli_main._restore_sigterm(previous)
        XRBridge._draw_eye = real_draw_eye
    record["code"] = code
    record["signals"] = interrupter.sent
    record["frames"] = frames[0]
    record["first_frame_s"] = None if first_frame[0] is None else round(first_frame[0], 3)
    record["capture"] = capture_state(capture)
    return record


def main(argv: list[str] | None = None) -> int:
    parser = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    parser.add_argument("--runs", type=int, required=True)
    parser.add_argument("--seed", type=int, default=0)
    parser.add_argument("--capture-root", type=Path, required=True)
    parser.add_argument("--start-window", type=float, default=0.3, help="seconds")
    parser.add_argument("--frame-window", type=float, default=0.25, help="seconds")
    parser.add_argument(
        "--swallowed", type=float, default=0.1, help="share of runs whose SIGINT is swallowed"
    )
    parser.add_argument(
        "--no-stop-check",
        action="store_true",
        help="run the bridge without the CLI's stop check (shows that a swallowed SIGINT is lost)",
    )
    args = parser.parse_args(argv)
    rng = np.random.default_rng(args.seed)
    the_scene = scene(rng)
    code = 0
    for index in range(args.runs):
        record = one_run(index, rng, args, the_scene)
        print(json.dumps(record), flush=True)
        code = record["code"]
    return code


if __name__ == "__main__":
    sys.exit(main())
