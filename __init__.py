# SPDX-License-Identifier: GPL-3.0-or-later
"""Extension root of BTF Materials: Blender loads this as ``bl_ext.<repo>.btf_materials``."""

from .btf_addon import register, unregister

__all__ = ["register", "unregister"]
