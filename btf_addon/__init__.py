# SPDX-License-Identifier: GPL-3.0-or-later
"""BTF Materials: measured BTF materials for Blender.

Layers (lower never imports higher; see docs/architecture.md):
core < cl, gl < render < controllers < blender. Only ``blender`` imports bpy, and only when
``register`` runs, so ``import btf_addon.core`` works in plain Python.
"""

from __future__ import annotations

__version__ = "0.1.0"


def register() -> None:
    from . import blender
    from .cli import blender_command

    blender.register()
    blender_command.register()  # `blender --command btf …`: the CLI for zip-only installs


def unregister() -> None:
    from . import blender
    from .cli import blender_command

    blender_command.unregister()
    blender.unregister()
