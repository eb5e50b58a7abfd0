"""A capture frame is written whole or not at all (issue 30 item 4: an interrupt between the
two eyes left a frame with only the left files, or a right EXR without its JSON)."""

from __future__ import annotations

import json
import os

import numpy as np
import pytest

from btf_addon.core.formats.imageio import read_exr
from btf_addon.xr import capture


def _eyes(rng):
    return [
        (name, rng.random((6, 8, 4)).astype(np.float32), {"lights_done": i + 1})
        for i, name in enumerate(("left", "right"))
    ]


def test_a_frame_has_both_eyes_each_with_its_json(tmp_path, rng):
    eyes = _eyes(rng)
    capture.write_frame(tmp_path, 7, eyes)
    assert sorted(p.name for p in tmp_path.iterdir()) == [
        "frame_00007_left.exr",
        "frame_00007_left.json",
        "frame_00007_right.exr",
        "frame_00007_right.json",
    ]
    for name, image, meta in eyes:
        record = json.loads((tmp_path / f"frame_00007_{name}.json").read_text())
        assert record == {"frame": 7, "eye": name, **meta, "image": f"frame_00007_{name}.exr"}
        np.testing.assert_array_equal(
            read_exr(tmp_path / record["image"]), image[::-1, :, :3]
        )  # row 0 at the top in the file


@pytest.mark.parametrize("where", ["right json", "right exr", "second rename", "last rename"])
def test_an_interrupt_anywhere_leaves_no_part_of_the_frame(tmp_path, rng, monkeypatch, where):
    capture.write_frame(tmp_path, 1, _eyes(rng))  # an earlier, complete frame stays
    before = sorted(p.name for p in tmp_path.iterdir())
    calls = {"json": 0, "exr": 0, "rename": 0}
    real_json, real_exr, real_replace = capture.atomic_write, capture.write_exr, os.replace

    def json_write(*args):
        calls["json"] += 1
        if where == "right json" and calls["json"] == 2:
            raise KeyboardInterrupt
        return real_json(*args)

    def exr_write(*args):
        calls["exr"] += 1
        if where == "right exr" and calls["exr"] == 2:
            raise KeyboardInterrupt
        return real_exr(*args)

    def rename(source, target):
        # Only the frame's own renames (staged → final), not those inside each atomic write.
        if ".staged." in str(source) and ".staged." not in str(target):
            calls["rename"] += 1
            if (where, calls["rename"]) in (("second rename", 2), ("last rename", 4)):
                raise KeyboardInterrupt
        return real_replace(source, target)

    monkeypatch.setattr(capture, "atomic_write", json_write)
    monkeypatch.setattr(capture, "write_exr", exr_write)
    monkeypatch.setattr(capture.os, "replace", rename)
    with pytest.raises(KeyboardInterrupt):
        capture.write_frame(tmp_path, 2, _eyes(rng))
    assert where.endswith("rename") == (calls["rename"] > 0)
    assert sorted(p.name for p in tmp_path.iterdir()) == before
