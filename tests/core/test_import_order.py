"""The layer order of docs/architecture.md, enforced for every pair of packages.

Every import in btf_addon (module level or inside a function: a deferred import is still a
dependency) is resolved to the package it names; a package may import only itself and packages
of a lower layer. Packages of the same layer are siblings and never import each other (cl/ and
gl/ are two back ends, not one)."""

from __future__ import annotations

import ast
import re

from helpers import ROOT

PACKAGE = ROOT / "btf_addon"

#: Bottom up. The same table is written in docs/architecture.md (checked below).
LAYERS: dict[str, int] = {
    "core": 1,
    "scene": 2,
    "render": 3,
    "cl": 4,
    "gl": 4,
    "controllers": 4,  # below xr/: the bridge builds its action set from it directly
    "xr": 5,
    "diagnostics": 5,
    "blender": 6,
    "cli": 7,
}


#: core/'s rooms, bottom up: the modules directly under core/ (the model, errors, angles,
#: colour, grids, mapping, files, memory, SSIM) are room "" and import no room; a room imports
#: itself and lower rooms only, never a sibling. Written in docs/architecture.md too.
CORE_ROOMS: dict[str, int] = {"": 0, "sampling": 1, "codecs": 2, "formats": 3, "encoders": 3}


def _imported_packages(path, root=ROOT, depth=1) -> list[tuple[int, str]]:
    """(line, package) for every import of a btf_addon package in one module; ``depth=2``:
    (line, "core/<room>") for imports of core's rooms ("core/" for its top-level modules)."""
    parts = path.relative_to(root).with_suffix("").parts  # ("btf_addon", "cl", "renderer")
    is_init = parts[-1] == "__init__"
    found = []
    for node in ast.walk(ast.parse(path.read_text())):
        if isinstance(node, ast.ImportFrom):
            if node.level == 0:
                names = [node.module or ""]
            else:
                # `from ..x import y` in btf_addon/a/b.py → btf_addon.x; an __init__ is its package.
                base = list(parts if is_init else parts[:-1])
                base = base[: len(base) - (node.level - 1)]
                target = [*base, *(node.module.split(".") if node.module else [])]
                names = (
                    [".".join(target)]
                    if node.module
                    else [".".join([*target, a.name]) for a in node.names]
                )
        elif isinstance(node, ast.Import):
            names = [a.name for a in node.names]
        else:
            continue
        for name in names:
            bits = name.split(".")
            if len(bits) >= 2 and bits[0] == "btf_addon" and depth == 1:
                found.append((node.lineno, bits[1]))
            elif len(bits) >= 3 and bits[:2] == ["btf_addon", "core"] and depth == 2:
                room = bits[2] if bits[2] in CORE_ROOMS else ""
                found.append((node.lineno, room))
    return found


def test_every_package_has_a_layer():
    packages = {p.name for p in PACKAGE.iterdir() if (p / "__init__.py").is_file()}
    assert packages <= set(LAYERS), f"packages without a layer: {packages - set(LAYERS)}"
    assert {"core", "scene", "render", "cl", "gl", "blender", "cli"} <= packages


def test_no_package_imports_a_higher_layer_or_a_sibling():
    offenders = []
    for path in sorted(PACKAGE.rglob("*.py")):
        rel = path.relative_to(PACKAGE)
        if len(rel.parts) < 2:
            continue  # btf_addon/__init__.py registers blender; __main__ runs cli: the roots
        own = rel.parts[0]
        for line, target in _imported_packages(path):
            if target == own or target not in LAYERS:
                continue
            if LAYERS[target] >= LAYERS[own]:
                offenders.append(
                    f"btf_addon/{rel}:{line} ({own}, layer {LAYERS[own]}) imports "
                    f"{target} (layer {LAYERS[target]})"
                )
    assert offenders == []


def test_cores_rooms_import_only_themselves_and_lower_rooms():
    rooms = {p.name for p in (PACKAGE / "core").iterdir() if (p / "__init__.py").is_file()}
    assert rooms == set(CORE_ROOMS) - {""}
    offenders = []
    for path in sorted((PACKAGE / "core").rglob("*.py")):
        rel = path.relative_to(PACKAGE / "core")
        own = rel.parts[0] if len(rel.parts) > 1 else ""
        for line, target in _imported_packages(path, depth=2):
            if target != own and CORE_ROOMS[target] >= CORE_ROOMS[own]:
                offenders.append(f"btf_addon/core/{rel}:{line} ({own or 'core/'}) imports {target}")
    assert offenders == []


def test_the_resolver_sees_relative_and_deferred_imports(tmp_path):
    """The check above could pass by seeing nothing: prove it resolves the forms the code uses."""
    module = tmp_path / "btf_addon" / "cl" / "probe.py"
    module.parent.mkdir(parents=True)
    module.write_text(
        "from ..gl.query import x\n"
        "from .. import blender\n"
        "def f():\n    from ...btf_addon.core import model\n    import btf_addon.cli.main\n"
    )
    found = [pkg for _, pkg in _imported_packages(module, root=tmp_path)]
    assert found[:2] == ["gl", "blender"] and "cli" in found


def test_architecture_doc_states_the_same_order():
    text = (ROOT / "docs" / "architecture.md").read_text()
    rows = re.findall(r"^\| (\d+) \| `btf_addon/(\w+)/`", text, flags=re.MULTILINE)
    documented = {name: int(order) for order, name in rows}
    assert documented == LAYERS
    rooms = re.findall(r"^\| 1\.(\d) \| `btf_addon/core/(\w*)/?`", text, flags=re.MULTILINE)
    assert {name: int(order) for order, name in rooms} == CORE_ROOMS
