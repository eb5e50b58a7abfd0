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


def _imported_packages(path, root=ROOT) -> list[tuple[int, str]]:
    """(line, package) for every import of a btf_addon package in one module."""
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
            if len(bits) >= 2 and bits[0] == "btf_addon":
                found.append((node.lineno, bits[1]))
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
