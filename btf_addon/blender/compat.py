"""The one place that knows which Blender version is running.

Every difference between the supported Blenders (4.2 LTS, 4.5 LTS, 5.0 on Python 3.11; 5.1 and
later on Python 3.13) is answered here, by a named helper, so the rest of the add-on never compares
``bpy.app.version`` itself. Add a helper here (with the version that changed and why) rather than
a version check at a call site; tests/blender/test_versions.py checks no other module does.
"""

from __future__ import annotations

import bpy

#: The oldest Blender the manifest accepts (``blender_version_min``); older ones never load us.
MINIMUM = (4, 2, 13)

#: The running Blender as (major, minor, patch).
VERSION: tuple[int, int, int] = tuple(bpy.app.version)


def at_least(major: int, minor: int, patch: int = 0) -> bool:
    """True when the running Blender is ``major.minor.patch`` or newer."""
    return (major, minor, patch) <= VERSION


def path_property_options() -> set[str]:
    """``options`` for a ``subtype="FILE_PATH"`` StringProperty whose value may be ``//``-relative.

    Blender 4.5 added ``PATH_SUPPORTS_BLEND_RELATIVE`` (and warns about ``//`` paths without it);
    4.2 rejects the unknown option, so it gets none.
    """
    return {"PATH_SUPPORTS_BLEND_RELATIVE"} if at_least(4, 5) else set()


def world_nodes_switched_off(world) -> bool:
    """True when ``world`` lights the scene with its flat ``World.color`` instead of its nodes.

    Blender before 5.0 has a per-World ``use_nodes`` switch; 5.0 always uses the nodes and
    deprecates the switch, so it is read only on older versions.
    """
    return not at_least(5, 0) and not world.use_nodes


def with_nodes(block):
    """``block`` (a new Material or World) with its node tree switched on; returns ``block``.

    Before 5.0, ``bpy.data.materials.new`` and ``bpy.data.worlds.new`` give ``node_tree = None``
    until ``use_nodes`` is set; 5.0 always creates the tree and deprecates ``use_nodes``.
    """
    if not at_least(5, 0):
        block.use_nodes = True
    return block


def exit_python(code: int = 0) -> None:
    """End a Python process that imported bpy as a module, after its work is done and saved.

    bpy 4.2 segfaults and bpy 4.5 hangs in their interpreter-exit teardown once an add-on was
    registered (seen with the pip builds 4.2.23 and 4.5.15); 5.0 and later exit cleanly. There,
    the output is flushed and the process leaves without the teardown; elsewhere it exits
    normally."""
    import os
    import sys

    if at_least(5, 0):
        sys.exit(code)
    sys.stdout.flush()
    sys.stderr.flush()
    os._exit(code)
