"""Helpers for the Blender tests (tests/blender)."""

from __future__ import annotations

import importlib
from types import SimpleNamespace

EXTENSION_MODULE = "bl_ext.user_default.btf_materials"


def extension_submodule(name: str):
    """A module of the installed extension, e.g. ``btf_addon.blender.world``."""
    return importlib.import_module(f"{EXTENSION_MODULE}.{name}")


def init_gpu_module(bpy) -> None:
    """Background Blender refuses to draw with ``gpu`` until one render has set up a context:
    render one tiny Workbench frame."""
    scene = bpy.context.scene
    engine, (x, y) = scene.render.engine, (scene.render.resolution_x, scene.render.resolution_y)
    camera = scene.camera
    temporary = None
    if camera is None:  # rendering needs a camera; add one for this frame only
        temporary = bpy.data.objects.new("gpu-init", bpy.data.cameras.new("gpu-init"))
        scene.collection.objects.link(temporary)
        scene.camera = temporary
    scene.render.engine = "BLENDER_WORKBENCH"
    scene.render.resolution_x = scene.render.resolution_y = 8
    try:
        bpy.ops.render.render(write_still=False)
    finally:
        scene.render.engine = engine
        scene.render.resolution_x, scene.render.resolution_y = x, y
        scene.camera = camera
        if temporary is not None:
            data = temporary.data
            bpy.data.objects.remove(temporary)
            bpy.data.cameras.remove(data)


def with_nodes(block):
    """A new Material or World with its node tree on, on every Blender version (through the
    extension's own ``compat``, the one place that knows versions)."""
    return extension_submodule("btf_addon.blender.compat").with_nodes(block)


def view_context(distance: float, width: int = 48, height: int = 32):
    """A 3D view's context as the viewport code reads it: a perspective view looking down −z
    at the origin from ``distance``, in a ``width`` × ``height`` region."""
    import mathutils  # only importable once bpy is

    view = mathutils.Matrix.Translation((0.0, 0.0, -distance))
    proj = mathutils.Matrix(((1.5, 0, 0, 0), (0, 2.25, 0, 0), (0, 0, -1.002, -0.2), (0, 0, -1, 0)))
    region_data = SimpleNamespace(
        perspective_matrix=proj @ view, view_matrix=view, is_perspective=True
    )
    return SimpleNamespace(
        region=SimpleNamespace(width=width, height=height), region_data=region_data
    )


def stand_in_engine():
    """The engine as view_draw uses it. Background Blender has no 3D view, so the display-space
    shader (colour management of the final blit) cannot be bound: that one call is skipped."""
    engine = SimpleNamespace(redraws=0, reports=[])
    engine.bind_display_space_shader = lambda scene: None
    engine.unbind_display_space_shader = lambda: None
    engine.tag_redraw = lambda: setattr(engine, "redraws", engine.redraws + 1)
    engine.report = lambda kind, message: engine.reports.append(message)
    return engine


def sphere_on_ground(bpy, tmp_path, material_source, size=(96, 64), segments=48, rings=24):
    """The tests' common scene: a smooth BTF sphere (``material_source``: a BTFbase folder or
    .btfm file) on a plain green ground under forest.exr, a camera looking slightly down, the
    BTF engine at ``size`` with 24 virtual lights, rendering to ``tmp_path/f12.exr``."""
    import math

    scene = bpy.context.scene
    scene.render.engine = "BTF_RENDER"
    scene.render.resolution_x, scene.render.resolution_y = size
    scene.render.resolution_percentage = 100
    scene.render.image_settings.file_format = "OPEN_EXR"
    scene.btf_render.lights_total = 24
    bpy.ops.mesh.primitive_uv_sphere_add(radius=1.0, segments=segments, ring_count=rings)
    bpy.ops.object.shade_smooth()
    material = with_nodes(bpy.data.materials.new("BTF"))
    material.btf.enabled = True
    material.btf.source = str(material_source)
    bpy.context.object.data.materials.append(material)
    bpy.ops.mesh.primitive_plane_add(size=6.0, location=(0.0, 0.0, -1.0))
    plain = with_nodes(bpy.data.materials.new("Plain"))
    plain.diffuse_color = (0.3, 0.6, 0.2, 1.0)
    bpy.context.object.data.materials.append(plain)
    cam = bpy.data.objects.new("Cam", bpy.data.cameras.new("Cam"))
    scene.collection.objects.link(cam)
    cam.location = (0.0, -5.0, 1.5)
    cam.rotation_euler = (math.radians(75), 0.0, 0.0)
    scene.camera = cam
    scene.world = forest_world(bpy, "W")
    scene.render.filepath = str(tmp_path / "f12.exr")
    return scene


def forest_world(bpy, name: str = "Forest", image: str = "forest"):
    """A World lit by one of Blender's bundled studiolights (forest.exr unless ``image`` names
    another) through an Environment Texture node."""
    from helpers import studiolights_dir

    world = with_nodes(bpy.data.worlds.new(name))
    texture = world.node_tree.nodes.new("ShaderNodeTexEnvironment")
    texture.image = bpy.data.images.load(str(studiolights_dir() / f"{image}.exr"))
    world.node_tree.links.new(
        texture.outputs["Color"], world.node_tree.nodes["Background"].inputs["Color"]
    )
    return world


class RecordingLayout:
    """Stands in for bpy.types.UILayout where a test draws a panel (background Blender has no
    window to draw in): records each ``prop`` (data, name; it must be a real property of that
    data), label, operator and node view, and hands itself out for rows, columns and boxes."""

    use_property_split = False
    active = True

    def __init__(self):
        self.props: list[tuple[object, str]] = []
        self.node_views: list[tuple] = []
        self.labels: list[str] = []
        self.operators: list[str] = []

    def prop(self, data, name, **_kw):
        assert name in data.bl_rna.properties, name  # a real property of that data
        self.props.append((data, name))

    def template_node_view(self, ntree, node, socket):
        self.node_views.append((ntree, node, socket))

    def template_icon(self, **_kw):
        pass

    def label(self, text="", **_kw):
        self.labels.append(text)

    def operator(self, idname, **_kw):
        from types import SimpleNamespace

        self.operators.append(idname)
        return SimpleNamespace()

    def _child(self, *_a, **_kw):
        return self

    row = column = box = split = _child

    def separator(self, **_kw):
        pass


def draw_panel(panel, context) -> RecordingLayout:
    """``panel``'s draw into a RecordingLayout, with ``context`` (a SimpleNamespace of what the
    panel reads)."""
    from types import SimpleNamespace

    layout = RecordingLayout()
    panel.draw(SimpleNamespace(layout=layout), context)
    return layout
