"""docs/user-guide.md stays true (issue 32 item 7): the messages it quotes are the messages the
code gives, and the UI paths it names (Render Properties › BTF Film › Transparent) lead to
labels Blender shows.

- Every double-quoted text of twelve or more characters in the guide is either a message,
  produced here by the code that gives it and matched against the quote (… stands for any
  text), or listed in NOT_MESSAGES with what it is instead. A new quote fails until it is one
  or the other.
- Every step of a `›` path is a label of a registered class or property (ours or Blender's),
  one of Blender's places listed in BLENDER_PLACES, or the start of such a label followed by
  the guide's own words.
No renders: a few seconds."""

from __future__ import annotations

import re
from types import SimpleNamespace

import pytest
from blender_helpers import extension_submodule
from helpers import ROOT

GUIDE = ROOT / "docs" / "user-guide.md"

#: Quoted texts that are not our messages, and what they are.
NOT_MESSAGES = {
    "pthread-AMD EPYC (PoCL 3.1+debian)": "a device name as a driver reports it",
    "pthread-AMD EPYC (PoCL 3.0-rc2, bundled)": "the same device through the bundled driver",
    "1 tile ≈ 12 mm on Cube": "the Mapping panel's tile row (tests/blender/test_mapping.py)",
    "unknown target CPU 'generic'": "the bundled PoCL's compiler error (not ours)",
    "unknown target CPU": "the same, shortened",
    "OpenCL runtime for Intel Core and Xeon processors": "Intel's product name",
    "what the file states": "the guide's gloss of a 0 Tile Size",
    "Scene Camera": "a choice of a property (checked as a label below)",
    "Reset Wiimote Bindings": "an operator's label (checked as a label below)",
    "VR screenshot": "a Wiimote action's name (checked below)",
    "Our own compressor: MLVQ encoder": "a heading quoted in the compress section",
    "… SVD encoder": "the same heading's SVD twin",
}

#: Places in Blender's UI that are editors, tabs or menus rather than labels of classes or
#: properties (Blender draws them from C or names them in its tab tooltips).
BLENDER_PLACES = {
    "Edit", "Preferences", "Get Extensions", "⌄", "Add-ons", "File Paths", "Render Properties",
    "Material Properties", "File", "Import", "External Data", "Object", "Render", "VR", "F3",
    "Scene", "Units", "World", "View Layer", "Output", "Render Engine", "Surface", "Passes",
    "Format", "Stereoscopy",
}  # fmt: skip


def guide_text() -> str:
    return re.sub(r"\s*\n\s*", " ", GUIDE.read_text(encoding="utf-8"))


def quotes() -> list[str]:
    found = re.findall(r'"([^"]*)"', guide_text())
    return [q for q in found if len(q) >= 12 and "`" not in q]


def matches(quote: str, message: str) -> bool:
    """``message`` has the quote's shape: its words in order, … for anything."""
    pattern = ".*".join(re.escape(part.strip()) for part in quote.split("…"))
    return re.search(pattern, message, flags=re.DOTALL) is not None


def real_messages(tmp_path) -> list[str]:
    """The messages the guide may quote, as the code gives them now."""
    paths = extension_submodule("btf_addon.blender.paths")
    final_render = extension_submodule("btf_addon.blender.final_render")
    programs = extension_submodule("btf_addon.cl.programs")
    mapping = extension_submodule("btf_addon.blender.ui.mapping")
    compress = extension_submodule("btf_addon.blender.tools.compress")
    encoded = tmp_path / "alu.btfm"
    encoded.write_bytes(bytes(120_000))
    alu = SimpleNamespace(meta=SimpleNamespace(width=64, height=64))
    ladder = extension_submodule("btf_addon.render.accuracy.ladder")
    report = extension_submodule("btf_addon.render.accuracy.report")
    settings = extension_submodule("btf_addon.render.settings")
    sampled = settings.RenderSettings(final_mode=settings.FinalMode.SAMPLED, samples=64)
    point = ladder.Point(ladder.Rung(sampled, "samples"), 1.0, 0.015, 0.001, 35.0)
    loose = tmp_path / "table.txt"
    loose.write_text("1 2 3\n")
    missing = paths.MissingSource("Wool", "//btf/wool", "//btf/wool: no such file or folder")
    compile_error = programs.OpenCLCompileError("render_direct.cl", "pthread-cpu", "1:2: error")
    playback = extension_submodule("btf_addon.render.bake_playback")
    light_bake = extension_submodule("btf_addon.render.light_bake")
    kept = light_bake.MeshBake("Ball", "", True, True, False, "on the ground", kept=True)
    return [
        playback.BakeStatus(played=("Suzanne",), stale=("Ground",)).line(),
        kept.line(),
        paths.source_hint(str(loose)),
        paths.source_hint(""),
        paths.missing_message([missing]),
        final_render.compile_error_message(compile_error),
        final_render.fallback_warning("OpenCL unavailable (no platform)", ""),
        mapping.ORIGINS["ASSUMED"](SimpleNamespace(assumed_texel_mm=0.1)),
        compress.summary(encoded, alu, "MLVQ", (38.2, 0.951), 12.0),
        report.recommendation_words(point, (320, 240)),
    ]


def test_every_quote_is_a_real_message_or_said_not_to_be(bpy_module, installed, tmp_path):
    messages = real_messages(tmp_path)
    wrong = [
        q for q in quotes() if q not in NOT_MESSAGES and not any(matches(q, m) for m in messages)
    ]
    assert not wrong, f"quoted in the guide but no message says it: {wrong}\n{messages}"
    stale = set(NOT_MESSAGES) - set(quotes())
    assert not stale, f"NOT_MESSAGES lists texts the guide no longer quotes: {stale}"


def test_a_changed_message_is_caught(bpy_module, installed, tmp_path):
    """The check itself: the guide's old wrong-folder quote no longer matches the message."""
    old = "pick the material's folder (the one holding all_materialInfo.txt …) or a .btfm file"
    assert not any(matches(old, m) for m in real_messages(tmp_path)[1:2])


def ui_labels(bpy) -> set[str]:
    """Every label Blender can show for a registered class or a property: bl_label of panels,
    menus and operators (Blender's and every add-on's, ours included), and the names of
    properties and enum items of every RNA struct reachable from them."""
    classes = [getattr(bpy.types, name, None) for name in dir(bpy.types)]
    bases = (bpy.types.Panel, bpy.types.Menu, bpy.types.Operator, bpy.types.PropertyGroup,
             bpy.types.AddonPreferences)  # fmt: skip
    stack = list(bases)
    while stack:  # registered subclasses: dir(bpy.types) lists only Blender's own
        cls = stack.pop()
        classes.append(cls)
        stack.extend(cls.__subclasses__())
    labels: set[str] = {extension_name()}  # the Add-ons list names the extension
    for module in dir(bpy.ops):  # operators written in C have no class in bpy.types
        for op in dir(getattr(bpy.ops, module)):
            labels.add(getattr(getattr(bpy.ops, module), op).get_rna_type().name)
    structs = []
    for cls in classes:
        label = getattr(cls, "bl_label", None)
        if isinstance(label, str):
            labels.add(label)
        rna = getattr(cls, "bl_rna", None)
        if rna is not None:
            structs.append(rna)
    seen: set[str] = set()
    while structs:
        rna = structs.pop()
        if rna.identifier in seen:
            continue
        seen.add(rna.identifier)
        labels.add(rna.name)
        for prop in rna.properties:
            labels.add(prop.name)
            for item in getattr(prop, "enum_items", ()):
                labels.add(item.name)
            fixed = getattr(prop, "fixed_type", None)
            if fixed is not None:
                structs.append(fixed)
    return {label.strip() for label in labels if label}


def extension_name() -> str:
    import tomllib

    return tomllib.loads((ROOT / "blender_manifest.toml").read_text())["name"]


def path_steps() -> list[list[str]]:
    """Each `A › B › C` of the guide as its steps, bold marks and code quotes dropped."""
    text = guide_text().replace("**", "").replace("*", "")
    chains = re.findall(r"(?:[^›|.;()]{1,60}? › )+[^›|.;()]{1,80}", text)
    return [[s.strip() for s in chain.split("›")] for chain in chains]


def known(step: str, labels: set[str], first: bool) -> bool:
    """``step`` is a label or place. The first step may end with one (after the sentence that
    leads to it), the last may start with one (before the sentence goes on); labels are in
    Title Case and prose is not, so the word next to the label must not be capitalised (else
    "Fixed Launch Split" would pass as the label "Fixed" followed by prose)."""
    parts = re.split(r"[,:(]", step)
    words = re.split(r"\s+", (parts[-1] if first else parts[0]).strip())
    candidates = labels | BLENDER_PLACES
    for i in range(len(words)):
        span, rest = (
            (words[i:], words[:i]) if first else (words[: len(words) - i], words[len(words) - i :])
        )
        text = " ".join(span)
        if text.rstrip("…") not in candidates and text not in candidates:
            continue
        neighbour = rest[-1] if first and rest else (rest[0] if rest else "")
        if not neighbour or not neighbour[0].isupper():
            return True
    return False


def test_every_ui_path_leads_to_a_label(bpy_module, installed):
    labels = ui_labels(bpy_module)
    steps = path_steps()
    assert len(steps) > 20  # the guide names many places: the extraction works
    unknown = [
        (" › ".join(chain), step)
        for chain in steps
        for i, step in enumerate(chain)
        if not known(step, labels, first=i == 0)
    ]
    assert not unknown, "\n".join(f"{step!r} in {chain!r}" for chain, step in unknown)


@pytest.mark.parametrize("renamed", ["Transparent", "Fixed Launch Split"])
def test_a_renamed_label_is_caught(bpy_module, installed, renamed):
    labels = ui_labels(bpy_module) - {renamed}
    assert renamed in ui_labels(bpy_module)
    assert not known(renamed, labels, first=False)
