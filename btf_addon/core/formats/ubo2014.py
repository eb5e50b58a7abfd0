"""Reader for UBO2014 ``.btf`` files in the DFMF form (Bonn's btflib, signature ``!DFMF08FCR``).

Layout (little endian; docs/formats.md has the table):

* signature, 10 bytes ``!DFMF08FCR`` (the trailing R: rotations are stored);
* meta block: ``u32 size`` (bytes of the block, counted from this field), ``u32 version``,
  ``char[80]`` measurement setup, image sensor, light source, ``f32 ppmm``, ``f32[3]`` RGB scale;
  version > 1: ``u32`` cosine flag; > 2: ``u32 n`` + n bytes of XML; > 3: ``u32`` channel count
  and per channel ``u32 n`` + n bytes of name;
* sampling: ``u32 nV``; per view ``f32 θ, φ`` (radians), ``u32 nL`` and nL × ``f32 θ, φ``;
* ``u32 width, height``; ``u32 n`` rotations + n × 9 ``f32``;
* DFMF: ``u32`` max components, ``i32`` colour model, ``f32[3]`` mean, ``f32[9]`` transform
  (row-major); per channel ``u8`` scalar size (2 half, 4 float, 8 double), ``u32`` components
  K, ``u32`` rows, ``u32`` columns, then S[K], U[rows × K], S·V[columns × K] (row-major).

Rows are direction pairs, view-major (row = view·nL + light); columns are texels, x fastest
(btflib reshapes ``U·SVᵀ`` to (nL, nV, width, height) column-major), y from the image's top
(``load_ubo2014`` flips it: texel row 0 is v = 0 here, as for every codec). Directions must
group into rings of equal θ (any distinct azimuths): the rows are reordered into ring order
and the azimuths kept per sample for the svd codec's interpolation (core/codecs/svd.py).
"""

from __future__ import annotations

from dataclasses import dataclass
from pathlib import Path

import numpy as np

from ..codecs.svd import SVDBTF, SVDParams
from ..errors import BTFFormatError, UnsupportedBTFError
from ..grid import RingGrid

SIGNATURE = b"!DFMF08FCR"
#: Bonn's other signatures: recognised so that the error can name them.
OTHER_SIGNATURES = (
    b"!FMF12FCER",
    b"!FMF06FCR",
    b"!FMF06FC",
    b"!PVF06FCR",
    b"!PVF06FC",
    b"!BDIF06R2!",
)
#: Limits that keep a corrupt count from allocating absurd amounts before reading.
MAX_DIRECTIONS = 10_000
MAX_TEXT = 1 << 20
#: Angles that agree within this many degrees are the same ring / the same azimuth step.
ANGLE_TOLERANCE_DEG = 0.05


def is_ubo2014(path: Path) -> bool:
    """Does the file start with one of Bonn's BTF signatures?"""
    try:
        with open(path, "rb") as fh:
            head = fh.read(10)
    except OSError:
        return False
    return head.startswith(SIGNATURE) or any(head.startswith(s) for s in OTHER_SIGNATURES)


@dataclass
class UBOMeta:
    """The meta block, sampling and DFMF header of a UBO2014 file."""

    version: int
    measurement_setup: str
    image_sensor: str
    light_source: str
    ppmm: float
    rgb_scale: tuple[float, float, float]
    cosine_in_data: bool
    xml: str
    channel_names: list[str]
    view_angles_rad: np.ndarray  # (nV, 2) θ, φ
    light_angles_rad: np.ndarray  # (nL, 2) θ, φ (the list every view shares)
    width: int
    height: int
    rotations: np.ndarray  # (n, 3, 3)
    colour_model: int
    colour_mean: np.ndarray  # (3,)
    colour_matrix: np.ndarray  # (3, 3)
    scalar_sizes: list[int]


class _Reader:
    """Bounds-checked little-endian reads over the file's bytes (a memory map)."""

    def __init__(self, data: np.ndarray, path: Path):
        self.data, self.path, self.pos = data, path, 0

    def need(self, n: int, what: str) -> None:
        if n < 0 or self.pos + n > len(self.data):
            raise BTFFormatError(
                f"{self.path}: truncated: {what} needs {n} bytes at offset {self.pos}, "
                f"{len(self.data) - self.pos} left"
            )

    def array(self, dtype: str, count: int, what: str) -> np.ndarray:
        dt = np.dtype(dtype)
        self.need(count * dt.itemsize, what)
        out = np.frombuffer(self.data, dt, count, self.pos)
        self.pos += count * dt.itemsize
        return out

    def u32(self, what: str) -> int:
        return int(self.array("<u4", 1, what)[0])

    def text(self, n: int, what: str) -> str:
        if n > MAX_TEXT:
            raise BTFFormatError(f"{self.path}: {what} claims {n} bytes")
        raw = self.array("u1", n, what).tobytes()
        return raw.split(b"\0", 1)[0].decode("utf-8", "replace").strip()


def _read_meta_block(r: _Reader) -> dict:
    start = r.pos
    size = r.u32("meta block size")
    version = r.u32("meta version")
    out = {
        "version": version,
        "measurement_setup": r.text(80, "measurement setup"),
        "image_sensor": r.text(80, "image sensor"),
        "light_source": r.text(80, "light source"),
        "ppmm": float(r.array("<f4", 1, "ppmm")[0]),
        "rgb_scale": tuple(float(v) for v in r.array("<f4", 3, "RGB scale")),
        "cosine_in_data": False,
        "xml": "",
        "channel_names": ["R", "G", "B"],
    }
    if version > 1:
        out["cosine_in_data"] = bool(r.u32("cosine flag"))
    if version > 2:
        out["xml"] = r.text(r.u32("XML length"), "XML")
    if version > 3:
        n = r.u32("channel count")
        if n > 64:
            raise BTFFormatError(f"{r.path}: meta block claims {n} channels")
        out["channel_names"] = [
            r.text(r.u32("channel name length"), "channel name") for _ in range(n)
        ]
    if r.pos - start != size:
        raise BTFFormatError(
            f"{r.path}: the meta block says {size} bytes, its fields take {r.pos - start}"
        )
    if not np.all(np.isfinite(out["rgb_scale"])) or not np.isfinite(out["ppmm"]):
        raise BTFFormatError(f"{r.path}: non-finite ppmm or RGB scale")
    return out


def _read_sampling(r: _Reader) -> tuple[np.ndarray, np.ndarray]:
    n_views = r.u32("view count")
    if not 1 <= n_views <= MAX_DIRECTIONS:
        raise BTFFormatError(f"{r.path}: {n_views} views (expected 1–{MAX_DIRECTIONS})")
    views = np.empty((n_views, 2))
    lights: np.ndarray | None = None
    for v in range(n_views):
        views[v] = r.array("<f4", 2, f"view {v} direction")
        n_lights = r.u32(f"view {v} light count")
        if not 1 <= n_lights <= MAX_DIRECTIONS:
            raise BTFFormatError(f"{r.path}: view {v} has {n_lights} lights")
        these = r.array("<f4", 2 * n_lights, f"view {v} lights").reshape(n_lights, 2)
        if lights is None:
            lights = these.astype(np.float64)
        elif these.shape != lights.shape or not np.allclose(these, lights, atol=1e-5):
            raise UnsupportedBTFError(
                f"{r.path}: view {v} has its own light directions; only files whose light list "
                "repeats for every view are supported"
            )
    assert lights is not None
    for what, a in (("view", views), ("light", lights)):
        if not np.all(np.isfinite(a)) or a[:, 0].min() < -1e-4 or a[:, 0].max() > np.pi / 2 + 1e-4:
            raise BTFFormatError(f"{r.path}: {what} θ outside [0, π/2] radians (or not finite)")
    return views, lights


def ring_order(
    angles_rad: np.ndarray, path: Path, what: str
) -> tuple[RingGrid, np.ndarray, np.ndarray]:
    """Directions (n, 2) θ, φ radians → their RingGrid, ``order`` (file index of ring-order
    sample i) and every sample's azimuth in degrees (ring order, increasing within a ring).
    Rings are the groups of equal θ; their azimuths may be rotated or uneven, but distinct."""
    theta = np.degrees(angles_rad[:, 0])
    phi = np.mod(np.degrees(angles_rad[:, 1]), 360.0)
    phi = np.where(phi > 360.0 - ANGLE_TOLERANCE_DEG, 0.0, phi)
    rings = np.unique(np.round(theta / ANGLE_TOLERANCE_DEG) * ANGLE_TOLERANCE_DEG)
    order, ring_theta, counts = [], [], []
    for t in rings:
        members = np.flatnonzero(np.abs(theta - t) <= ANGLE_TOLERANCE_DEG)
        members = members[np.argsort(phi[members], kind="stable")]
        n = len(members)
        if t <= ANGLE_TOLERANCE_DEG and n != 1:
            raise UnsupportedBTFError(f"{path}: {n} {what} directions at the pole")
        if n > 1 and np.min(np.diff(phi[members])) <= ANGLE_TOLERANCE_DEG:
            raise BTFFormatError(
                f"{path}: two {what} directions share θ = {t:.2f}° and the same azimuth"
            )
        order.extend(members.tolist())
        ring_theta.append(float(np.mean(theta[members])))
        counts.append(n)
    if len(order) != len(theta):
        raise UnsupportedBTFError(f"{path}: {what} directions do not group into rings of equal θ")
    order_arr = np.asarray(order)
    return RingGrid(tuple(ring_theta), tuple(counts)), order_arr, phi[order_arr]


_SCALARS = {2: "<f2", 4: "<f4", 8: "<f8"}


def read_ubo2014(path: str | Path) -> tuple[UBOMeta, list[np.ndarray], list[np.ndarray]]:
    """A DFMF file → (meta, U per channel (rows, K) float32, S·V per channel (cols, K)
    float32), exactly as stored (file row order; no colour transform)."""
    path = Path(path)
    try:
        size = path.stat().st_size
        data = np.memmap(path, dtype=np.uint8, mode="r") if size else np.zeros(0, np.uint8)
    except (OSError, ValueError) as exc:
        raise BTFFormatError(f"{path}: cannot read ({exc})") from None
    r = _Reader(data, path)
    r.need(10, "signature")
    signature = bytes(data[:10])
    if signature != SIGNATURE:
        other = next((s for s in OTHER_SIGNATURES if signature.startswith(s)), None)
        if other:
            raise UnsupportedBTFError(
                f"{path}: UBO2014 {other.decode()} files are not supported; only DFMF "
                f"({SIGNATURE.decode()}), the form the Bonn database publishes"
            )
        raise BTFFormatError(f"{path}: not a UBO2014 DFMF file (signature {signature!r})")
    r.pos = 10
    meta = _read_meta_block(r)
    views, lights = _read_sampling(r)
    width, height = r.u32("width"), r.u32("height")
    if not (1 <= width <= 1 << 16 and 1 <= height <= 1 << 16):
        raise BTFFormatError(f"{path}: texture size {width}×{height} is out of range")
    n_rot = r.u32("rotation count")
    if n_rot > width * height:
        raise BTFFormatError(f"{path}: {n_rot} rotations for {width}×{height} texels")
    rotations = r.array("<f4", 9 * n_rot, "rotations").reshape(n_rot, 3, 3).astype(np.float32)
    max_components = r.u32("component count")
    colour_model = int(r.array("<i4", 1, "colour model")[0])
    mean = r.array("<f4", 3, "colour mean").astype(np.float64)
    matrix = r.array("<f4", 9, "colour transform").reshape(3, 3).astype(np.float64)
    n_channels = len(meta["channel_names"])
    if n_channels != 3:
        raise UnsupportedBTFError(f"{path}: {n_channels} channels; only 3-channel files")
    pairs, texels = len(views) * len(lights), width * height
    u, sv, sizes = [], [], []
    for c in range(n_channels):
        scalar = int(r.array("u1", 1, f"channel {c} scalar size")[0])
        if scalar not in _SCALARS:
            raise BTFFormatError(f"{path}: channel {c}: scalar size {scalar} (expected 2, 4, 8)")
        k, rows, cols = (r.u32(f"channel {c} {w}") for w in ("components", "rows", "columns"))
        if not 1 <= k <= max(max_components, 1) or {rows, cols} != {pairs, texels}:
            raise BTFFormatError(
                f"{path}: channel {c}: {k} components of {rows}×{cols}, expected ≤ "
                f"{max_components} components of {pairs} pairs × {texels} texels"
            )
        # Sizes are checked against the bytes left before anything is allocated.
        r.need(scalar * k * (1 + rows + cols), f"channel {c} factors")
        s = r.array(_SCALARS[scalar], k, f"channel {c} S")
        uc = r.array(_SCALARS[scalar], rows * k, f"channel {c} U").reshape(rows, k)
        vc = r.array(_SCALARS[scalar], cols * k, f"channel {c} SV").reshape(cols, k)
        if rows == texels and cols == pairs and pairs != texels:
            uc, vc = vc, uc  # the transposed variant: texels stacked as rows
        for name, a in (("S", s), ("U", uc), ("S·V", vc)):
            if not np.all(np.isfinite(a)):
                raise BTFFormatError(f"{path}: channel {c}: NaN or infinite values in {name}")
        u.append(uc.astype(np.float32))
        sv.append(vc.astype(np.float32))
        sizes.append(scalar)
    if r.pos != len(data):
        raise BTFFormatError(f"{path}: {len(data) - r.pos} bytes of trailing data")
    return (
        UBOMeta(
            version=meta["version"],
            measurement_setup=meta["measurement_setup"],
            image_sensor=meta["image_sensor"],
            light_source=meta["light_source"],
            ppmm=meta["ppmm"],
            rgb_scale=meta["rgb_scale"],
            cosine_in_data=meta["cosine_in_data"],
            xml=meta["xml"],
            channel_names=meta["channel_names"],
            view_angles_rad=views,
            light_angles_rad=lights,
            width=width,
            height=height,
            rotations=rotations,
            colour_model=colour_model,
            colour_mean=mean,
            colour_matrix=matrix,
            scalar_sizes=sizes,
        ),
        u,
        sv,
    )


def load_ubo2014(path: str | Path) -> SVDBTF:
    """A DFMF file → an SVDBTF with its rows in ring order."""
    path = Path(path)
    meta, u, sv = read_ubo2014(path)
    view_grid, view_order, view_phi = ring_order(meta.view_angles_rad, path, "view")
    light_grid, light_order, light_phi = ring_order(meta.light_angles_rad, path, "light")
    n_lights = len(meta.light_angles_rad)
    rows = (view_order[:, None] * n_lights + light_order[None, :]).ravel()
    tile = (meta.width / meta.ppmm, meta.height / meta.ppmm) if meta.ppmm > 0 else (10.0, 10.0)
    params = SVDParams(
        name=path.stem,
        width=meta.width,
        height=meta.height,
        view_grid=view_grid,
        light_grid=light_grid,
        colour_model=meta.colour_model,
        pca_matrix=tuple(float(v) for v in meta.colour_matrix.ravel()),
        colour_mean=tuple(float(v) for v in meta.colour_mean),
        rgb_scale=meta.rgb_scale,
        cosine_in_data=meta.cosine_in_data,
        tile_size_mm=tile,
        view_phi=_unless_regular(view_grid, view_phi),
        light_phi=_unless_regular(light_grid, light_phi),
    )
    # File texel x + width·y counts rows from the image's top; ours from v = 0 (the bottom).
    flipped = [a.reshape(meta.height, meta.width, -1)[::-1].reshape(len(a), -1) for a in sv]
    btf = SVDBTF(params, [a[rows] for a in u], flipped)
    btf.meta.extra["file_format"] = "ubo2014-dfmf"
    btf.meta.extra["scalar_bytes"] = meta.scalar_sizes
    btf.meta.extra["rotations"] = len(meta.rotations)
    return btf


def _unless_regular(grid: RingGrid, phi: np.ndarray) -> tuple[float, ...] | None:
    """None when the azimuths are the grid's own k·360°/n (within the angle tolerance)."""
    if np.allclose(phi, grid.angles_deg()[1], atol=ANGLE_TOLERANCE_DEG):
        return None
    return tuple(float(v) for v in phi)
