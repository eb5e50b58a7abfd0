"""UBO2003 and ATRIUM image sets: a zip or folder of 81 × 81 images, one per (light, view)
direction pair, named ``tl{θl:03} pl{φl:03} tv{θv:03} pv{φv:03}`` in whole degrees — JPEG
(8-bit, UBO2003, 256²) or Radiance ``.hdr`` (float, ATRIUM, 800²) — read into a dense BTF on
the UBO2003 ring grid (core/grid.py).

Values: JPEG pixels are 8-bit reflectance factors (255 = the white standard, as BTFbase's MLVQ
data, which was compressed from these images), HDR pixels reflectance factors (1 = white);
value = factor/π (docs/conventions.md). Image row 0 is the top (v = 1).

JPEG decoding uses Pillow (libjpeg-turbo), imported only when a JPEG set is read: a baseline
and progressive JPEG decoder of our own would be thousands of lines and ~100× slower in numpy,
and OpenEXR reads no JPEG. Pillow is not bundled with the extension (six more platform wheels);
without it a JPEG set is one clear error naming the package. HDR uses core/formats/radiance_hdr.py.

A full set does not fit a dense table at full resolution (UBO2003: 81·81·256²·3 floats =
5.2 GB), so ``texels`` box-filters every image to texels × texels while reading (one image in
memory at a time) and a set that would exceed ``max_bytes`` is refused with the size it needs.
"""

from __future__ import annotations

import io
import re
import zipfile
from collections.abc import Callable, Iterator
from pathlib import Path

import numpy as np

from ..codecs.dense import DenseBTF
from ..errors import BTFError, BTFFormatError
from ..grid import UBO2003
from .radiance_hdr import decode_hdr

NAME = re.compile(
    r"tl\s*(\d{1,3})\s*pl\s*(\d{1,3})\s*tv\s*(\d{1,3})\s*pv\s*(\d{1,3})\.(jpe?g|hdr)$",
    re.IGNORECASE,
)
MAX_BYTES = 2 << 30


def angles_of(name: str) -> tuple[int, int, int, int, str] | None:
    """A member name → (θl, φl, θv, φv, extension) or None when it is not a set image."""
    m = NAME.search(Path(name).name)
    if not m:
        return None
    return (*(int(g) for g in m.groups()[:4]), m.group(5).lower())


def _members(path: Path) -> tuple[list[str], Callable[[str], bytes], Callable[[], None]]:
    if path.is_dir():
        names = sorted(str(p.relative_to(path)) for p in path.rglob("*") if p.is_file())
        return names, lambda n: (path / n).read_bytes(), lambda: None
    try:
        archive = zipfile.ZipFile(path)
    except (OSError, zipfile.BadZipFile) as exc:
        raise BTFFormatError(f"{path}: not a readable zip of images ({exc})") from None
    return archive.namelist(), archive.read, archive.close


def is_image_set(path: Path) -> bool:
    """A zip, or a folder, holding at least one image named by its angles."""
    if path.is_file() and path.suffix.lower() != ".zip":
        return False
    try:
        names, _, close = _members(path)
    except BTFError:
        return False
    close()
    return any(angles_of(n) for n in names)


def _decode(data: bytes, kind: str, name: str) -> np.ndarray:
    """One image → (H, W, 3) float32 reflectance factors."""
    if kind == "hdr":
        return decode_hdr(data, name)
    try:
        from PIL import Image
    except ImportError:
        raise BTFError(
            f"{name}: JPEG image sets need the Pillow package (pip install pillow), which the "
            "extension does not bundle; convert the set with the command line "
            "(python -m btf_addon convert SET out.btfm) where Pillow is installed"
        ) from None
    try:
        with Image.open(io.BytesIO(data)) as img:
            rgb = np.asarray(img.convert("RGB"), dtype=np.float32)
    except OSError as exc:
        raise BTFFormatError(f"{name}: not a readable JPEG ({exc})") from None
    return rgb / 255.0


def _box(image: np.ndarray, texels: int | None) -> np.ndarray:
    h, w, _ = image.shape
    if texels is None or (texels == h and texels == w):
        return image
    fy, fx = h // texels, w // texels
    if fy < 1 or fx < 1:
        raise BTFError(f"cannot reduce {w}×{h} images to {texels}² texels")
    crop = image[: fy * texels, : fx * texels]
    return crop.reshape(texels, fy, texels, fx, 3).mean(axis=(1, 3))


def _index(grid_angles: tuple[np.ndarray, np.ndarray]) -> dict[tuple[int, int], int]:
    theta, phi = grid_angles
    return {(round(t), round(p) % 360): i for i, (t, p) in enumerate(zip(theta, phi, strict=True))}


def load_image_set(
    path: str | Path,
    texels: int | str | None = None,
    max_bytes: int = MAX_BYTES,
    progress: Callable[[int, int], None] | None = None,
) -> DenseBTF:
    """A UBO2003/ATRIUM zip or folder → DenseBTF (81 × 81 on the UBO2003 grid).
    texels: box-filter each image to texels × texels (None: full size; "auto": the largest
    power-of-two reduction within ``max_bytes``, noted in ``meta.extra['reduced']``)."""
    path = Path(path)
    names, read, close = _members(path)
    try:
        index = _index(UBO2003.angles_deg())
        found: dict[tuple[int, int], tuple[str, str]] = {}
        for n in names:
            a = angles_of(n)
            if a is None:
                continue
            tl, pl, tv, pv, kind = a
            key_l, key_v = index.get((tl, pl % 360)), index.get((tv, pv % 360))
            if key_l is None or key_v is None:
                raise BTFFormatError(f"{path}: {n}: angles not on the UBO2003 81-direction grid")
            if (key_v, key_l) in found:
                raise BTFFormatError(f"{path}: two images for the same angles: {n}")
            found[(key_v, key_l)] = (n, kind)
        expected = UBO2003.size**2
        if len(found) != expected:
            raise BTFFormatError(
                f"{path}: {len(found)} of the {expected} images (tl pl tv pv) are present"
                + ("" if found else "; is this a UBO2003/ATRIUM image set?")
            )
        data: np.ndarray | None = None
        note = None
        for count, ((v, li), (n, kind)) in enumerate(sorted(found.items())):
            image = _decode(read(n), kind, f"{path}: {n}")
            if texels == "auto":  # the largest power-of-two reduction that fits max_bytes
                side = min(image.shape[:2])
                texels = side
                while texels > 1 and expected * texels * texels * 12 > max_bytes:
                    texels //= 2
                if texels != side:
                    note = f"read at {texels}×{texels} texels of {image.shape[1]}×{image.shape[0]}"
            image = _box(image, texels)
            if data is None:
                h, w, _ = image.shape
                need = expected * h * w * 3 * 4
                if need > max_bytes:
                    raise BTFError(
                        f"{path}: {w}×{h} texels × 81 × 81 directions need "
                        f"{need / 2**30:.1f} GiB as a dense table; pass a smaller texel count "
                        f"(e.g. 64 → {expected * 64 * 64 * 12 / 2**30:.2f} GiB)"
                    )
                data = np.empty((UBO2003.size, UBO2003.size, h, w, 3), dtype=np.float32)
            if image.shape != data.shape[2:]:
                raise BTFFormatError(
                    f"{path}: {n} is {image.shape[1]}×{image.shape[0]}, "
                    f"the others {data.shape[3]}×{data.shape[2]}"
                )
            data[v, li] = image[::-1]  # row 0 of an image is its top: v = 1
            if progress:
                progress(count + 1, expected)
    finally:
        close()
    assert data is not None
    btf = DenseBTF(data / np.float32(np.pi), UBO2003, UBO2003, name=path.stem)
    kinds = sorted({kind for _, kind in found.values()})
    btf.meta.extra["file_format"] = "ubo-image-set-" + "+".join(kinds)
    if note:
        btf.meta.extra["reduced"] = note
    return btf


def iter_set_names(suffix: str = ".hdr") -> Iterator[tuple[str, int, int]]:
    """(file name, view index, light index) for every direction pair of the UBO2003 grid,
    named as the image sets are (for writing test sets and exports)."""
    theta, phi = UBO2003.angles_deg()
    for v in range(UBO2003.size):
        for li in range(UBO2003.size):
            name = (
                f"tl{round(theta[li]):03} pl{round(phi[li]):03} "
                f"tv{round(theta[v]):03} pv{round(phi[v]):03}{suffix}"
            )
            yield name, v, li
