"""What accuracy costs in time, for one scene: the ladder of quality knobs, the error of each
rung against a high-quality reference, the Pareto front, a recommendation for a time budget or
a target error, and the prediction of full-resolution time. bpy-free and device-free: rendering
is a callable the caller passes (blender/accuracy/run.py binds it to the OpenCL final render).

Knobs are data (``KNOBS``): one ``Knob`` per RenderSettings field (or any other value the render
callable understands, passed through ``Rung.extra``). Adding a knob is one entry.

The ladder sweeps one knob at a time from the scene's own settings (the user's shot), once for
every value of each *branch* knob (the final mode: its values decide which other knobs apply),
so every curve passes through the settings the user has now.

Error metrics (against the reference, both on RGB):
- relative RMSE: sqrt(mean((a − r)²)) / sqrt(mean(r²)), the project's measure everywhere
  (docs/accuracy.md), linear in radiance;
- 1 − SSIM: the structural similarity of Wang et al. 2004 (Gaussian window σ = 1.5 px, the
  paper's constants) on the luminance of the *displayed* images (sRGB, clipped at 1). Chosen
  because it is the standard, well-studied perceptual measure, weighs noise on flat regions
  and loss of structure as a viewer does, and needs nothing beyond numpy (FLIP would fit
  rendering better but is a far larger model to reimplement and validate).

Time model: each rung's render time is ``overhead + rate · work`` where ``work`` = pixels ×
the product of the *work* knobs that apply (lights: pixel·light; samples: pixel·sample) and
(overhead, rate) are fitted per cost class (the values of the *class* knobs that apply: final
mode, bounces). Full-resolution time = the measured fixed setup (export, device, upload) +
the class's overhead + rate × the full-resolution work.
"""

from __future__ import annotations

import enum
import math
import time
from collections.abc import Callable, Iterable, Mapping, Sequence
from dataclasses import dataclass, field, fields, replace
from typing import Any

import numpy as np

from ...core import ssim
from ...core.colour import srgb_encode
from ..settings import FinalMode, Lighting, RenderSettings, blender_float


class Role(enum.Enum):
    WORK = "work"  # render time grows in proportion to the value (lights, samples)
    CLASS = "class"  # the value changes the cost per unit of work (mode, bounces)


@dataclass(frozen=True)
class Knob:
    """One quality knob. ``values`` are the ladder's rungs, cheap first (the scene's own value
    is added to them); ``applies(settings)`` says whether the knob matters under those
    settings; a ``branch`` knob's values each get their own sweep of the other knobs."""

    name: str  # a RenderSettings field, or a key of Rung.extra for the render callable
    label: str  # the UI's words
    values: tuple
    applies: Callable[[RenderSettings], bool]
    role: Role
    branch: bool = False


def _environment(s: RenderSettings) -> bool:
    return s.lighting is Lighting.ENVIRONMENT


KNOBS: tuple[Knob, ...] = (
    Knob(
        "final_mode",
        "Final Render",
        (FinalMode.VIRTUAL, FinalMode.SAMPLED),
        _environment,
        Role.CLASS,
        branch=True,
    ),
    Knob(
        "lights_total",
        "Virtual Lights",
        (4, 16, 64, 256, 1024),
        lambda s: _environment(s) and not s.sampled,
        Role.WORK,
    ),
    Knob("samples", "Samples", (1, 4, 16, 64, 256), lambda s: s.sampled, Role.WORK),
    Knob("max_bounces", "Max Bounces", (0, 1, 2, 4), lambda s: s.sampled, Role.CLASS),
    # Anti-aliasing: off traces pixel centres (aliasing is error against the filtered
    # reference). Its subpixels split the N lights, so they change the cost per pixel·light
    # rather than multiplying the work: a class, not a work knob.
    Knob("use_antialiasing", "Anti-Aliasing", (False, True), _environment, Role.CLASS),
    Knob(
        "aa_samples",
        "AA Samples",
        (1, 4, 16),
        lambda s: s.use_antialiasing and not s.sampled and _environment(s),
        Role.CLASS,
    ),
    # Not a RenderSettings field: every BTF material's texel filter (Rung.extra), applied by
    # the render callable (blender/accuracy/run.py).
    # Under the headlight nothing is laddered: the reference samples the World, which the
    # headlight does not show.
    Knob("texel_filter", "Texel Filter", ("NEAREST", "LINEAR"), _environment, Role.CLASS),
    # Clamp Indirect: what the clamp's bias costs against the unclamped reference, only where
    # there is indirect light to clamp.
    Knob(
        "clamp_indirect",
        "Clamp Indirect",
        (0.0, 10.0),
        lambda s: s.sampled and s.max_bounces > 0,
        Role.CLASS,
    ),
    # Samples per camera ray: only where camera rays go through the pixel filter.
    Knob(
        "samples_per_camera_ray",
        "Samples per Camera Ray",
        (1, 4),
        lambda s: s.sampled and s.use_antialiasing,
        Role.CLASS,
    ),
    # Adaptive sampling: off beside on, and on, what each Noise Threshold saves and costs
    # (the samples a stopped pixel did not take, the noise it kept). A class: it changes the
    # time per pixel·sample of the samples knob.
    Knob(
        "use_adaptive_sampling", "Adaptive Sampling", (False, True), lambda s: s.sampled, Role.CLASS
    ),
    Knob(
        "adaptive_threshold",
        "Noise Threshold",
        tuple(blender_float(t) for t in (0.005, 0.01, 0.05)),  # as a scene holds them
        lambda s: s.sampled and s.use_adaptive_sampling,
        Role.CLASS,
    ),
)

_FIELDS = {f.name for f in fields(RenderSettings)}

#: The quick estimate (Quality vs Time's default): the one work knob of the scene's own mode
#: (samples when Sampled, virtual lights otherwise), every other setting as the scene has it.
QUICK_VALUES = {"samples": (4, 16, 64, 128), "lights_total": (16, 64, 256, 1024)}


def quick_knobs() -> tuple[Knob, ...]:
    """The knobs of the quick estimate: no branch (the scene's final mode only), the work knob
    over QUICK_VALUES."""
    return tuple(replace(k, values=QUICK_VALUES[k.name]) for k in KNOBS if k.name in QUICK_VALUES)


def all_knobs(knobs: Sequence[Knob] | None = None) -> Sequence[Knob]:
    """``knobs``, or the module's ``KNOBS`` read at call time (not bound as a default, so a
    caller — or a test of the core ladder — can narrow the set in one place)."""
    return KNOBS if knobs is None else knobs


@dataclass(frozen=True)
class Rung:
    """One render of the ladder: the settings, the knob it varies (``sweep``) and the branch
    it belongs to (``branch``: the branch knobs' values), ``extra`` values for knobs that are
    not RenderSettings fields."""

    settings: RenderSettings
    sweep: str
    branch: tuple = ()
    extra: tuple = ()  # (name, value) pairs: hashable

    def value(self, name: str) -> Any:
        if name in _FIELDS:
            return getattr(self.settings, name)
        return dict(self.extra).get(name)

    def knob_values(self, knobs: Sequence[Knob] | None = None) -> dict[str, Any]:
        """{name: value} of every knob that applies to this rung (enums as their names)."""
        knobs = all_knobs(knobs)
        return {k.name: _plain(self.value(k.name)) for k in knobs if k.applies(self.settings)}

    @property
    def series(self) -> str:
        """The curve this rung is drawn on: branch values + the swept knob."""
        labels = {k.name: k.label for k in all_knobs()}
        sweep = labels.get(self.sweep, self.sweep)
        branch = ", ".join(str(_plain(v)).lower() for v in self.branch)
        return f"{branch}: {sweep}" if branch else sweep


def _plain(value: Any) -> Any:
    return value.name if isinstance(value, enum.Enum) else value


def _with(settings: RenderSettings, extra: dict, name: str, value: Any):
    if name in _FIELDS:
        return replace(settings, **{name: value}), extra
    return settings, {**extra, name: value}


def ladder(
    base: RenderSettings,
    knobs: Sequence[Knob] | None = None,
    base_extra: Mapping[str, Any] | None = None,
) -> list[Rung]:
    """Every rung: for each combination of the branch knobs' values, each other knob that
    applies swept over its values (plus the scene's own), the rest at the scene's values.
    Duplicates (the base appears in every sweep) are kept once, in the first sweep."""
    knobs = all_knobs(knobs)
    extra0 = dict(base_extra or {})
    branches: list[tuple[RenderSettings, dict, tuple]] = [(base, extra0, ())]
    for knob in (k for k in knobs if k.branch):
        grown = []
        for settings, extra, labels in branches:
            if not knob.applies(settings):
                grown.append((settings, extra, labels))
                continue
            for value in knob.values:
                s, e = _with(settings, extra, knob.name, value)
                grown.append((s, e, (*labels, value)))
        branches = grown
    rungs, seen = [], set()
    for settings, extra, labels in branches:
        for knob in (k for k in knobs if not k.branch and k.applies(settings)):
            current = settings if knob.name in _FIELDS else None
            own = getattr(current, knob.name) if current else extra.get(knob.name)
            values = list(knob.values)
            if own is not None and own not in values:
                values.append(own)
                values.sort(key=_sort_key)
            for value in values:
                s, e = _with(settings, extra, knob.name, value)
                key = (s, tuple(sorted(e.items())))
                if key in seen:
                    continue
                seen.add(key)
                rungs.append(Rung(s, knob.name, labels, tuple(sorted(e.items()))))
    return rungs


def _sort_key(value: Any):
    return value.value if isinstance(value, enum.Enum) else value


def reference_settings(base: RenderSettings, samples: int = 1024, bounces: int = 8):
    """The reference: the World sampled continuously (no virtual-light approximation), many
    samples, many bounces, another seed than the ladder's (its noise is independent of the
    rungs', so a rung is not rewarded for sharing the reference's first samples)."""
    return replace(
        base,
        final_mode=FinalMode.SAMPLED,
        use_antialiasing=True,  # the true image is the film-filtered one
        samples=samples,
        max_bounces=max(bounces, base.max_bounces),
        clamp_indirect=0.0,  # unbiased: a clamp's bias is error
        use_adaptive_sampling=False,  # every pixel converged alike
        seed=base.seed + 7919,
    )


# ---------------------------------------------------------------------------------------------
# Error metrics


def relative_rmse(image: np.ndarray, reference: np.ndarray) -> float:
    """(h, w, 3) linear RGB against the same-shaped reference: sqrt(mean((a − r)²)) /
    sqrt(mean(r²)). An all-black reference gives the absolute RMSE (nothing to divide by)."""
    a, r = _rgb(image), _rgb(reference)
    rms_ref = float(np.sqrt(np.mean(r**2)))
    rmse = float(np.sqrt(np.mean((a - r) ** 2)))
    return rmse / rms_ref if rms_ref > 0 else rmse


def error_map(image: np.ndarray, reference: np.ndarray) -> np.ndarray:
    """(h, w) float64: each pixel's RMS error over RGB divided by the reference's RMS over the
    whole image, so that sqrt(mean(map²)) equals ``relative_rmse``: a heat map of where in the
    image the error sits, on the same scale as the headline number."""
    a, r = _rgb(image), _rgb(reference)
    rms_ref = float(np.sqrt(np.mean(r**2))) or 1.0
    return np.sqrt(np.mean((a - r) ** 2, axis=-1)) / rms_ref


def display_luminance(image: np.ndarray) -> np.ndarray:
    """(h, w, 3) linear RGB → (h, w) luminance of the displayed image: sRGB-encoded after
    clipping to [0, 1] (the Standard view), Rec. 709 weights on the encoded values (as SSIM
    is applied to displayed images)."""
    c = srgb_encode(np.clip(np.nan_to_num(_rgb(image)), 0.0, 1.0))
    return c @ np.array([0.2126, 0.7152, 0.0722])


def ssim_map(image: np.ndarray, reference: np.ndarray) -> np.ndarray:
    """(h, w) float64 SSIM per pixel (1 = identical) of the displayed luminances (core/ssim.py,
    dynamic range 1)."""
    return ssim.ssim_map(display_luminance(image), display_luminance(reference), peak=1.0)


def ssim_loss(image: np.ndarray, reference: np.ndarray) -> float:
    """1 − mean SSIM: 0 for identical images, larger for worse."""
    return float(1.0 - np.mean(ssim_map(image, reference)))


def _rgb(image: np.ndarray) -> np.ndarray:
    a = np.asarray(image, dtype=np.float64)
    if a.ndim != 3 or a.shape[-1] < 3:
        raise ValueError(f"expected an (h, w, 3 or 4) image, got shape {a.shape}")
    return a[..., :3]


# ---------------------------------------------------------------------------------------------
# Time model


def work_units(rung: Rung, pixels: int, knobs: Sequence[Knob] | None = None) -> float:
    """pixels × the product of the work knobs that apply (pixel·lights, pixel·samples)."""
    units = float(pixels)
    for knob in all_knobs(knobs):
        if knob.role is Role.WORK and knob.applies(rung.settings):
            units *= float(rung.value(knob.name))
    return units


def cost_class(rung: Rung, knobs: Sequence[Knob] | None = None) -> tuple:
    """The values of the class knobs that apply: rungs with equal classes cost the same per
    unit of work."""
    values = (
        (k.name, _plain(rung.value(k.name)))
        for k in all_knobs(knobs)
        if k.role is Role.CLASS and k.applies(rung.settings)
    )
    return tuple((name, v) for name, v in values if v is not None)  # None: a knob not swept


@dataclass(frozen=True)
class Timing:
    rung: Rung
    pixels: int
    seconds: float


@dataclass(frozen=True)
class TimeModel:
    """seconds(rung, pixels) = setup + overhead[class] + rate[class] · work(rung, pixels).
    ``setup_seconds``: the once-per-render cost measured apart (export, device, upload)."""

    setup_seconds: float
    classes: Mapping[tuple, tuple[float, float]]  # class → (overhead s, seconds per unit)
    knobs: tuple[Knob, ...] | None = None  # None: all_knobs() when used
    residual: float = 0.0  # largest |measured − fitted| / fitted over the rungs fitted

    def predict(self, rung: Rung, pixels: int) -> float:
        key = cost_class(rung, self.knobs)
        if key not in self.classes:
            raise KeyError(f"no timing measured for the cost class {key}")
        overhead, rate = self.classes[key]
        return self.setup_seconds + overhead + rate * work_units(rung, pixels, self.knobs)

    def rates(self) -> dict[str, float]:
        """{class as text: nanoseconds per unit of work} for reports."""
        return {_class_text(k): rate * 1e9 for k, (_o, rate) in self.classes.items()}


def _class_text(key: tuple) -> str:
    return ", ".join(f"{name}={value}" for name, value in key) or "all"


def fit_time_model(
    timings: Iterable[Timing], setup_seconds: float = 0.0, knobs: Sequence[Knob] | None = None
) -> TimeModel:
    """Least squares per cost class: t = overhead + rate · work with overhead ≥ 0 and rate > 0
    (a noisy negative intercept is dropped and the rate refitted through the origin). A class
    measured at one work size takes the median overhead of the fitted classes (0 if none)."""
    groups: dict[tuple, list[tuple[float, float]]] = {}
    for t in timings:
        groups.setdefault(cost_class(t.rung, knobs), []).append(
            (work_units(t.rung, t.pixels, knobs), t.seconds)
        )
    fitted: dict[tuple, tuple[float, float]] = {}
    single = []
    for key, points in groups.items():
        w = np.array([p[0] for p in points])
        s = np.array([p[1] for p in points])
        if len(np.unique(w)) < 2:
            single.append(key)
            continue
        rate, overhead = np.polyfit(w, s, 1)
        if overhead < 0 or rate <= 0:
            overhead = max(float(overhead), 0.0) if rate > 0 else 0.0
            rate = float(np.sum(w * (s - overhead)) / np.sum(w * w))
        fitted[key] = (float(overhead), max(float(rate), 1e-15))
    common = float(np.median([o for o, _r in fitted.values()])) if fitted else 0.0
    for key in single:
        w, s = np.mean([p[0] for p in groups[key]]), np.mean([p[1] for p in groups[key]])
        overhead = min(common, 0.5 * float(s))
        fitted[key] = (overhead, max(float(s) - overhead, 1e-12) / float(w))
    residual = 0.0
    for key, points in groups.items():
        overhead, rate = fitted[key]
        for w, t in points:
            fit = overhead + rate * w
            residual = max(residual, abs(t - fit) / fit)
    return TimeModel(float(setup_seconds), fitted, tuple(all_knobs(knobs)), residual)


# ---------------------------------------------------------------------------------------------
# Results, Pareto front, recommendation


@dataclass
class Point:
    """One measured rung: errors at the preview size, the measured and predicted times."""

    rung: Rung
    seconds: float  # measured render time at the preview size
    rmse: float  # relative RMSE against the reference
    ssim_loss: float  # 1 − SSIM of the displayed images
    predicted_seconds: float = math.nan  # full resolution, from the time model
    seeds: int = 1  # images the errors are pooled over (verify_recommendation)
    rmse_upper: float = math.nan  # one-sided 90 % bound of the pooled rmse (seeds > 1)


def pareto_front(points: Sequence[Point], metric: str = "rmse") -> list[int]:
    """Indices of the points no other point beats in both predicted time and ``metric``
    (equal in one and better in the other counts as beating), by increasing time."""
    order = sorted(
        range(len(points)),
        key=lambda i: (points[i].predicted_seconds, getattr(points[i], metric)),
    )
    front, best = [], math.inf
    for i in order:
        error = getattr(points[i], metric)
        if error < best:
            front.append(i)
            best = error
    return front


@dataclass(frozen=True)
class Recommendation:
    index: int  # into the points
    reason: str
    met: bool  # whether the budget/target could be met


def recommend(
    points: Sequence[Point],
    budget: float | None = None,
    target: float | None = None,
    metric: str = "rmse",
) -> Recommendation | None:
    """The rung to use. With a time budget (s at full resolution): the lowest error that fits
    it. With a target error: the fastest rung that reaches it. With both: the fastest rung that
    reaches the target within the budget, else the lowest error within the budget. When
    nothing qualifies the nearest miss is returned with ``met`` False. None without points."""
    if not points:
        return None
    idx = range(len(points))

    def err(i):
        return getattr(points[i], metric)

    def secs(i):
        return points[i].predicted_seconds

    fits = [i for i in idx if budget is None or secs(i) <= budget]
    if target is not None:
        good = [i for i in fits if err(i) <= target]
        if good:
            i = min(good, key=lambda i: (secs(i), err(i)))
            within = f" within {budget:g} s" if budget is not None else ""
            return Recommendation(i, f"the fastest reaching {target:.3g} {metric}{within}", True)
        if budget is None:
            i = min(idx, key=lambda i: (err(i), secs(i)))
            return Recommendation(
                i, f"no rung reaches {target:.3g} {metric}: the most accurate", False
            )
    if budget is not None:
        if fits:
            i = min(fits, key=lambda i: (err(i), secs(i)))
            missed = target is not None
            why = f"the most accurate within {budget:g} s"
            if missed:
                why += f" (none reaches {target:.3g} {metric} in it)"
            return Recommendation(i, why, not missed)
        i = min(idx, key=lambda i: (secs(i), err(i)))
        return Recommendation(i, f"nothing fits {budget:g} s: the fastest", False)
    i = min(idx, key=lambda i: (err(i), secs(i)))
    return Recommendation(i, "the most accurate (no budget or target given)", True)


# ---------------------------------------------------------------------------------------------
# The run


RenderFn = Callable[[Rung, Callable[[float], bool]], np.ndarray | None]


@dataclass
class Estimate:
    """The state of a run; everything a report needs. ``points`` grow as rungs finish."""

    base: RenderSettings
    preview_size: tuple[int, int]
    full_size: tuple[int, int]
    reference: RenderSettings
    setup_seconds: float = 0.0
    reference_seconds: float = math.nan
    reference_image: np.ndarray | None = None
    points: list[Point] = field(default_factory=list)
    images: list[np.ndarray] = field(default_factory=list)  # per point, (h, w, 3)
    rungs_total: int = 0
    model: TimeModel | None = None
    interrupted: bool = False
    device: str = ""
    scene: str = ""
    #: The light bake's sweep (render/accuracy/bake_sweep.py ``to_json``'s rows; empty: none)
    bake: list[dict] = field(default_factory=list)

    @property
    def preview_pixels(self) -> int:
        return self.preview_size[0] * self.preview_size[1]

    @property
    def full_pixels(self) -> int:
        return self.full_size[0] * self.full_size[1]

    def refit(self) -> None:
        """The time model from the rungs so far, and each point's full-resolution time."""
        timings = [Timing(p.rung, self.preview_pixels, p.seconds) for p in self.points]
        self.model = fit_time_model(timings, self.setup_seconds)
        for p in self.points:
            p.predicted_seconds = self.model.predict(p.rung, self.full_pixels)


def run(
    estimate: Estimate,
    rungs: Sequence[Rung],
    render: RenderFn,
    *,
    on_progress: Callable[[float, str], None] | None = None,
    on_point: Callable[[Estimate], None] | None = None,
    cancelled: Callable[[], bool] = lambda: False,
    clock: Callable[[], float] = time.perf_counter,
) -> Estimate:
    """Render the reference (unless ``estimate`` has one), then every rung, scoring each as it
    finishes. ``render(rung, progress)`` returns the (h, w, ≥3) image, or None when
    ``progress(fraction)`` returned False (cancelled: the rung is dropped). ``on_point`` sees
    the estimate after the reference and after every rung (write the JSON there: a
    KeyboardInterrupt keeps what is done). Time is measured with ``clock`` around each
    ``render`` call (tests inject one)."""
    estimate.rungs_total = len(rungs)
    # Progress shares: the reference counts as much as the whole ladder's most expensive rung
    # would suggest is unknowable up front, so it is given a fixed third of the bar.
    ref_share = 1 / 3 if estimate.reference_image is None else 0.0
    step = (1 - ref_share) / max(len(rungs), 1)

    def report(fraction: float, text: str) -> bool:
        if on_progress is not None:
            on_progress(min(max(fraction, 0.0), 1.0), text)
        return not cancelled()

    if estimate.reference_image is None:
        # Bilinear texels: the reference is the smooth surface the texels sample.
        ref_rung = Rung(estimate.reference, "reference", extra=(("texel_filter", "LINEAR"),))
        t0 = clock()
        image = render(ref_rung, lambda f: report(f * ref_share, "reference"))
        if image is None or cancelled():
            estimate.interrupted = True
            return estimate
        estimate.reference_seconds = clock() - t0
        estimate.reference_image = np.asarray(image, dtype=np.float32)[..., :3]
        if on_point is not None:
            on_point(estimate)
    done = {p.rung for p in estimate.points}
    for n, rung in enumerate(rungs):
        if rung in done:
            continue
        start = ref_share + n * step
        label = describe_rung(rung)
        if not report(start, label):
            estimate.interrupted = True
            break
        t0 = clock()
        image = render(rung, lambda f, s=start, t=label: report(s + f * step, t))
        seconds = clock() - t0
        if image is None or cancelled():
            estimate.interrupted = True
            break
        image = np.asarray(image, dtype=np.float32)[..., :3]
        ref = estimate.reference_image
        estimate.points.append(
            Point(rung, seconds, relative_rmse(image, ref), ssim_loss(image, ref))
        )
        estimate.images.append(image)
        estimate.refit()
        if on_point is not None:
            on_point(estimate)
    report(1.0, "done")
    return estimate


def verify_recommendation(
    estimate: Estimate,
    render: RenderFn,
    budget: float | None = None,
    target: float | None = None,
    max_seeds: int = 4,
    cancelled: Callable[[], bool] = lambda: False,
    rounds: int = 3,
) -> Recommendation | None:
    """Re-measure the recommended rung's error over more pixels before it is stated.

    A noisy rung's error is a mean over pixels of a heavy-tailed quantity: rare very bright
    pixels (fireflies) carry much of the mean square, and a small preview usually holds fewer
    of them than the full-size image will, so one preview understates the error. The rung is
    rendered again with other seeds, k images in all (k = full pixels ÷ preview pixels, at
    most ``max_seeds``), and its errors become the pooled ones (mean squared error and mean
    SSIM over the k images, against the one reference). Deterministic rungs (no sampling) need
    nothing. If the pooled error moves the recommendation, the new one is verified too (up to
    ``rounds`` times). Returns the final recommendation."""
    k = max(1, min(max_seeds, math.ceil(estimate.full_pixels / estimate.preview_pixels)))
    ref = estimate.reference_image
    for _ in range(rounds):
        rec = recommend(estimate.points, budget, target)
        if rec is None or ref is None:
            return rec
        i = rec.index
        point = estimate.points[i]
        if point.seeds >= k or not point.rung.settings.sampled:
            return rec
        mse = [(point.rmse * _rms(ref)) ** 2]
        ssim = [point.ssim_loss]
        for extra in range(1, k):
            seed = point.rung.settings.seed + 104729 * extra  # away from the reference's
            rung = replace(point.rung, settings=replace(point.rung.settings, seed=seed))
            image = render(rung, lambda _f: not cancelled())
            if image is None or cancelled():
                return rec
            image = np.asarray(image, dtype=np.float32)[..., :3]
            mse.append(relative_rmse(image, ref) ** 2 * _rms(ref) ** 2)
            ssim.append(ssim_loss(image, ref))
        scale = _rms(ref) or 1.0
        point.rmse = math.sqrt(float(np.mean(mse))) / scale
        # The mean of k per-image squared errors, plus 1.28 standard errors (one-sided 90 %
        # under a normal approximation of that mean): a stated bound, not a guarantee.
        upper = float(np.mean(mse)) + 1.2816 * float(np.std(mse, ddof=1)) / math.sqrt(k)
        point.rmse_upper = math.sqrt(upper) / scale
        point.ssim_loss = float(np.mean(ssim))
        point.seeds = k
    return recommend(estimate.points, budget, target)


def _rms(image: np.ndarray) -> float:
    return float(np.sqrt(np.mean(_rgb(image) ** 2)))


def reference_noise(estimate: Estimate) -> float | None:
    """The reference's own relative noise, estimated from the samples sweep: rung and
    reference noise are independent, so err² = σ²/n + floor² per rung of n samples; the two
    rungs with the most samples give σ², and the reference's noise is σ/√n_ref (its extra
    bounces are ignored: an estimate). None when the sweep does not allow one. Errors near
    this value are the reference's noise, not the rung's."""
    sweep = sorted(
        (p for p in estimate.points if p.rung.sweep == "samples"),
        key=lambda p: p.rung.settings.samples,
    )
    if len(sweep) < 2:
        return None
    a, b = sweep[-2], sweep[-1]
    n1, n2 = a.rung.settings.samples, b.rung.settings.samples
    sigma2 = (a.rmse**2 - b.rmse**2) / (1 / n1 - 1 / n2)
    if not sigma2 > 0:
        return None
    return math.sqrt(sigma2 / estimate.reference.samples)


def describe_rung(rung: Rung, knobs: Sequence[Knob] | None = None) -> str:
    """ "Sampled: samples=16, max_bounces=4" style text of the knobs that apply."""
    values = rung.knob_values(knobs)
    mode = values.pop("final_mode", None)
    body = ", ".join(f"{k}={v}" for k, v in values.items())
    return f"{mode.lower()}: {body}" if mode else body or "as the scene"


#: How a knob's value reads in a sentence ("64 samples", "Linear texels").
_WORDS: dict[str, Callable[[Any], str]] = {
    "final_mode": lambda v: "Sampled" if v == "SAMPLED" else "Virtual Lights",
    "lights_total": lambda v: f"{v} virtual lights",
    "samples": lambda v: f"{v} sample{'s' if v != 1 else ''}",
    "max_bounces": lambda v: f"{v} bounce{'s' if v != 1 else ''}",
    "use_antialiasing": lambda v: "anti-aliased" if v else "no anti-aliasing",
    "aa_samples": lambda v: f"{v} subpixel{'s' if v != 1 else ''}",
    "texel_filter": lambda v: f"{str(v).title()} texels",
    "clamp_indirect": lambda v: f"indirect clamped at {v:g}" if v else "no clamp",
    "samples_per_camera_ray": lambda v: f"{v} sample{'s' if v != 1 else ''} per camera ray",
    "use_adaptive_sampling": lambda v: "adaptive sampling" if v else "no adaptive sampling",
    "adaptive_threshold": lambda v: f"noise threshold {v:g}",
}


def describe_words(rung: Rung, knobs: Sequence[Knob] | None = None) -> str:
    """The rung in a designer's words: "64 samples" when only the swept knob differs from the
    scene's settings, else every knob that applies ("Sampled, 64 samples, 4 bounces, …")."""
    values = rung.knob_values(knobs)
    words = [_WORDS.get(k, lambda v, k=k: f"{k} {v}")(v) for k, v in values.items()]
    sweep = rung.sweep
    if not rung.branch and sweep in values:
        return _WORDS.get(sweep, lambda v: f"{sweep} {v}")(values[sweep])
    return ", ".join(words) or "the scene's settings"


#: Relative RMSE → what a viewer sees, for the panel's sentence: thresholds where the error
#: stops being visible in a still image (≈ 1 %), is barely visible (2 %), and so on.
QUALITY_WORDS = ((0.01, "indistinguishable"), (0.02, "barely visible"), (0.05, "slight"),
                 (0.1, "visible"), (math.inf, "strong"))  # fmt: skip


def quality_words(rmse: float, sampled: bool) -> str:
    """ "noise barely visible", "differences slight": noise for the Sampled mode (it averages
    out), differences for Virtual Lights (a fixed error: banding, missing light)."""
    what = "noise" if sampled else "differences from the true image"
    for bound, word in QUALITY_WORDS:
        if rmse <= bound:
            if word == "indistinguishable":
                return "indistinguishable from the reference"
            return f"{what} {word}"
    return f"{what} unknown"


def settings_json(settings: RenderSettings) -> dict[str, Any]:
    return {f.name: _plain(getattr(settings, f.name)) for f in fields(settings)}


def settings_from_json(values: Mapping[str, Any], base: RenderSettings) -> RenderSettings:
    """RenderSettings from ``settings_json``'s form over ``base`` (unknown keys ignored, so a
    report from a build with more knobs still applies what this one knows)."""
    known = {k: v for k, v in values.items() if k in _FIELDS}
    for name, kind in (("lighting", Lighting), ("final_mode", FinalMode)):
        if name in known:
            known[name] = kind[known[name]]
    return replace(base, **known)
