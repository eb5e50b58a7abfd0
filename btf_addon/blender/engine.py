"""The BTF render engine: thin methods into final_render and viewport (Cycles' habit)."""

from __future__ import annotations

import bpy

from ..cl import warm
from . import final_render, viewport
from .addon import ENGINE_ID


class BTFRenderEngine(bpy.types.RenderEngine):
    bl_idname = ENGINE_ID
    bl_label = "BTF"
    # Material previews are drawn by this engine too, so BTF materials preview as they render.
    bl_use_preview = True
    # No GPU context for render(): F12 ray traces through OpenCL and needs none. Asking for one
    # made Blender create an EGL context for every render, which prints EGL_BAD_MATCH lines
    # while it probes configs and aborts the process (libepoxy) where no EGL is usable. The
    # GLSL fallback makes its own headless context (blender/glsl_fallback.py).
    bl_use_gpu_context = False
    # Our materials are BTF settings, not node trees: keep Blender's own material UI.
    bl_use_shading_nodes_custom = False

    def render(self, depsgraph):
        try:
            final_render.render(self, depsgraph)
        except KeyboardInterrupt:
            # Ctrl-C or SIGTERM of a command-line render: Blender would print the traceback of
            # an exception leaving this callback and carry on. The command's handler recorded
            # the signal and ends the run (cli/render_command.py _after_interrupt).
            self.report({"WARNING"}, "render interrupted")

    def update_render_passes(self, scene=None, renderlayer=None):
        """Passes this engine writes, shown in the compositor when enabled on the view layer."""
        self.register_pass(scene, renderlayer, "Combined", 4, "RGBA", "COLOR")
        if renderlayer.use_pass_z:
            self.register_pass(scene, renderlayer, "Depth", 1, "Z", "VALUE")
        if renderlayer.use_pass_normal:
            self.register_pass(scene, renderlayer, "Normal", 3, "XYZ", "VECTOR")
        if renderlayer.use_pass_uv:
            self.register_pass(scene, renderlayer, "UV", 3, "UVA", "VECTOR")

    def view_update(self, context, depsgraph):
        viewport.view_update(self, context, depsgraph)

    def view_draw(self, context, depsgraph):
        viewport.view_draw(self, context, depsgraph)

    def free(self):
        state = getattr(self, "btf_viewport", None)
        if state is not None:
            state.free_buffers()


#: Panels listing 'BLENDER_RENDER' that show what this engine ignores or has its own panel for
#: (panels.py): the Light panel (BTF_LIGHT_PT_light), light probes (not rendered), the
#: View Layer's filter and passes (BTF_VIEWLAYER_PT_passes: the passes F12 writes).
EXCLUDED_PANELS = {
    "VIEWLAYER_PT_filter",
    "VIEWLAYER_PT_layer_passes",
    "DATA_PT_light",
    "DATA_PT_lightprobe",
    "DATA_PT_lightprobe_display",
    "DATA_PT_lightprobe_parallax",
    "DATA_PT_lightprobe_visibility",
    "DATA_PT_context_lightprobe",
}


def compatible_panels():
    """Built-in panels shown for Eevee/Workbench that make sense for this engine as well."""
    panels = [p for p in bpy.types.Panel.__subclasses__() if hasattr(p, "COMPAT_ENGINES")]
    # A subclass (the node editor's copy of a panel) shares its parent's set: exclude the set.
    excluded = {id(p.COMPAT_ENGINES) for p in panels if p.__name__ in EXCLUDED_PANELS}
    for panel in panels:
        engines = panel.COMPAT_ENGINES
        if "BLENDER_RENDER" in engines and id(engines) not in excluded:
            yield panel


def register() -> None:
    bpy.utils.register_class(BTFRenderEngine)
    for panel in compatible_panels():
        panel.COMPAT_ENGINES.add(ENGINE_ID)
    warm.start()  # pyopencl's import off the first F12's clock (cl/warm.py)


def unregister() -> None:
    for panel in compatible_panels():
        panel.COMPAT_ENGINES.discard(ENGINE_ID)
    bpy.utils.unregister_class(BTFRenderEngine)
    warm.wait(10.0)  # a disabled add-on leaves no thread of its own running
