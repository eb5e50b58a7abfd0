"""The zip serves every supported Blender: bundled wheels per Python and platform, pinned test
environments per Blender version, and version checks only in blender/compat.py. No bpy needed."""

from __future__ import annotations

import re
import tomllib
from collections import defaultdict

from helpers import ROOT

# The Pythons the supported Blenders run: 4.2–5.0 run 3.11, 5.1 and later 3.13.
PYTHON_TAGS = {"cp311", "cp313"}
# The manifest's platforms and how their wheels' platform tags end.
PLATFORM_SUFFIXES = {
    "linux-x64": "x86_64",
    "windows-x64": "win_amd64",
    "macos-arm64": "arm64",
}
# Packages bundled for one platform only, on purpose: PoCL, the CPU OpenCL driver, exists on PyPI
# for Linux x86-64 alone (Windows and macOS users get OpenCL from their GPU driver or the OS).
ONE_PLATFORM = {"pocl_binary_distribution": "linux-x64"}
# Pure-Python packages cut per platform from a published all-platform wheel by
# tools/slim_wheels.py: each carries its platform's native loader only.
PER_PLATFORM_PURE = {"pyopenxr"}


def manifest() -> dict:
    with (ROOT / "blender_manifest.toml").open("rb") as fh:
        return tomllib.load(fh)


def bundled() -> list[tuple[str, str, str, str]]:
    """(name, version, python tag, platform tag) of each wheel the manifest bundles."""
    out = []
    for entry in manifest()["wheels"]:
        name, version, python, _abi, platform = entry.rsplit("/", 1)[1][: -len(".whl")].split("-")
        out.append((name, version, python, platform))
    return out


def pins(path) -> dict[str, str]:
    """``name==version`` lines of a requirements file, following ``-r`` includes."""
    found: dict[str, str] = {}
    for line in path.read_text().splitlines():
        line = line.split("#", 1)[0].strip()
        if line.startswith("-r "):
            found.update(pins(path.parent / line[3:].strip()))
        elif "==" in line:
            name, version = line.split("==")
            found[name.strip().lower().replace("-", "_")] = version.strip()
    return found


def test_every_compiled_wheel_exists_for_each_python_and_platform():
    compiled: dict[tuple[str, str], set[tuple[str, str]]] = defaultdict(set)
    for name, version, python, platform in bundled():
        if name in ONE_PLATFORM or name in PER_PLATFORM_PURE:
            continue  # test_pocl_is_bundled_for_linux_only, test_slim_wheels_one_per_platform
        if platform == "any":
            assert python in {"py3", "py2.py3"}, (name, python)
            continue
        for manifest_platform, suffix in PLATFORM_SUFFIXES.items():
            if platform.endswith(suffix):
                compiled[(name, version)].add((python, manifest_platform))
    assert len(compiled) == 6, sorted(compiled)  # pyopencl, moderngl, glcontext, hidapi, …
    wanted = {(python, platform) for python in PYTHON_TAGS for platform in PLATFORM_SUFFIXES}
    for package, have in compiled.items():
        assert have == wanted, f"{package}: missing {sorted(wanted - have)}"
    assert set(manifest()["platforms"]) == set(PLATFORM_SUFFIXES)


def test_pocl_is_bundled_for_linux_only():
    """F12 ray traces out of the box on Linux: the CPU OpenCL driver comes in the Linux zip (a
    58 MB wheel, about 108 MB installed; one build serves every Python). It installs into
    pyopencl/.libs, where the bundled pyopencl's ICD loader finds it without a system ICD."""
    pocl = [w for w in bundled() if w[0] == "pocl_binary_distribution"]
    assert len(pocl) == 1, pocl
    _name, _version, python, platform = pocl[0]
    assert python == "py2.py3" and platform.endswith(PLATFORM_SUFFIXES[ONE_PLATFORM[pocl[0][0]]])


def test_slim_wheels_one_per_platform():
    """pyopenxr comes as one derived wheel per platform (tools/slim_wheels.py), each pure
    Python plus that platform's loader, and every one of them is derived, never fetched."""
    import sys

    sys.path.insert(0, str(ROOT / "tools"))
    from slim_wheels import SLIM

    for name in PER_PLATFORM_PURE:
        wheels = [w for w in bundled() if w[0] == name]
        platforms = {
            p for p, suffix in PLATFORM_SUFFIXES.items() for w in wheels if w[3].endswith(suffix)
        }
        assert platforms == set(PLATFORM_SUFFIXES) and len(wheels) == len(platforms), wheels
        assert all(w[2] == "py3" for w in wheels), wheels
    derived = [
        e.rsplit("/", 1)[1]
        for e in manifest()["wheels"]
        if e.split("/")[-1].startswith(tuple(PER_PLATFORM_PURE))
    ]
    assert sorted(derived) == sorted(SLIM)


def test_numpy_is_never_bundled():
    """Blender ships its own numpy (1.26 up to 5.0, 2.x from 5.1): a bundled one would shadow it."""
    assert not [w for w in bundled() if w[0].lower() == "numpy"]


def test_bundled_versions_are_the_tested_versions():
    """Every test environment installs the versions the zip bundles (requirements/common.txt)."""
    common = pins(ROOT / "requirements" / "common.txt")
    for name, version, _python, _platform in bundled():
        assert common.get(name.lower()) == version, (name, version, common.get(name.lower()))


def test_each_tested_blender_has_a_pinned_environment():
    """Makefile's BLENDERS ↔ one requirements file each, pinning that bpy and a numpy it takes."""
    makefile = (ROOT / "Makefile").read_text()
    versions = re.search(r"^BLENDERS := (.+)$", makefile, re.M).group(1).split()
    main = re.search(r"^MAIN_BLENDER := (.+)$", makefile, re.M).group(1).strip()
    assert main in versions and {"4.2", "4.5"} <= set(versions)
    for version in versions:
        path = ROOT / (
            "requirements-dev.txt" if version == main else f"requirements/blender-{version}.txt"
        )
        pinned = pins(path)
        assert pinned["bpy"].startswith(f"{version}."), (path, pinned["bpy"])
        numpy_major = int(pinned["numpy"].split(".")[0])
        # bpy up to 5.0 needs numpy < 2 (Python 3.11); from 5.1 numpy >= 2.2 (Python 3.13).
        old = tuple(map(int, version.split("."))) <= (5, 0)
        assert numpy_major == (1 if old else 2), (version, pinned["numpy"])


def test_manifest_minimum_is_compat_minimum():
    """blender_version_min and compat.MINIMUM say the same version (compat imports bpy, so its
    source is read, not imported)."""
    source = (ROOT / "btf_addon" / "blender" / "compat.py").read_text()
    minimum = re.search(r"^MINIMUM = \((\d+), (\d+), (\d+)\)$", source, re.M).groups()
    assert manifest()["blender_version_min"] == ".".join(minimum)
    assert "blender_version_max" not in manifest()  # nothing breaks on a newer Blender yet


def test_version_checks_live_only_in_compat():
    """One place knows Blender versions: no other module reads bpy.app.version."""
    pattern = re.compile(r"bpy\.app\.version(?!_string)\b")
    offenders = [
        str(path.relative_to(ROOT))
        for path in sorted((ROOT / "btf_addon").rglob("*.py"))
        if path.name != "compat.py" and pattern.search(path.read_text())
    ]
    assert offenders == []
