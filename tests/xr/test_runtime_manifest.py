"""What the bridge says of XR_RUNTIME_JSON (xr/session.py ``manifest_state``): the file, its
JSON and the runtime library it names, resolved as the OpenXR loader resolves it (relative to
the manifest's folder; a bare file name goes to the system's library search)."""

import json

from btf_addon.xr.session import manifest_state


def _manifest(tmp_path, library) -> str:
    path = tmp_path / "rt.json"
    path.write_text(
        json.dumps({"file_format_version": "1.0.0", "runtime": {"library_path": library}})
    )
    return str(path)


def test_each_state_is_named(tmp_path):
    assert manifest_state(str(tmp_path / "none.json")) == "does not exist"
    bad = tmp_path / "bad.json"
    bad.write_text("{not json")
    assert manifest_state(str(bad)).startswith("exists, but is not a runtime manifest")
    (tmp_path / "lib").mkdir()
    (tmp_path / "lib" / "librt.so").write_bytes(b"")
    found = manifest_state(_manifest(tmp_path, "lib/librt.so"))
    assert found == f"exists; runtime library {tmp_path / 'lib' / 'librt.so'}"
    missing = manifest_state(_manifest(tmp_path, "lib/other.so"))
    other = tmp_path / "lib" / "other.so"
    assert missing == f"exists, but the runtime library it names, {other}, does not exist"
    dotted = manifest_state(_manifest(tmp_path, "./lib/../lib/librt.so"))
    assert dotted == found
    absolute = manifest_state(_manifest(tmp_path, str(tmp_path / "lib" / "librt.so")))
    assert absolute.endswith(str(tmp_path / "lib" / "librt.so"))
    assert "system's library search" in manifest_state(_manifest(tmp_path, "libopenxr_x.so"))
    assert "empty" in manifest_state(_manifest(tmp_path, ""))
