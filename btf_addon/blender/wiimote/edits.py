"""Controller actions → scene edits (bpy). One function per action; the session
(``session.py``) calls ``apply_edit`` for every Edit of the step function.

Targets, in the words of issue 13:
- materials: the active object's active slot steps through the file's BTF materials (those with
  ``material.btf.enabled``, sorted by name); with a single BTF material, its ``btf.source``
  steps through the BTF sources beside it (folders and ``.btfm`` files of the same parent);
- objects: the active object steps through the view layer's mesh objects, sorted by name;
- environment: the Z rotation of the World's Mapping node in front of its Environment Texture
  (the node ``export/world.py`` reads; a TEXTURE-type Mapping turns the other way; inserted
  with Generated coordinates when the texture has none);
- exposure: ``btf.exposure`` of the active object's BTF material (without one: of every BTF
  material in view);
- lights per frame and progressive: ``scene.btf_render``;
- orbit and zoom: the 3D viewport's view when one is given (``region_3d``), else the scene
  camera around the active object (or the origin); reset view restores what was saved at start.
  A session that started in a 3D view and lost it (the area was closed or joined) skips them
  with a message rather than move the camera instead.
- in a running VR session (``XrSessionState.is_running``): orbit and zoom move the VR
  navigation instead (``navigation_location/rotation/scale``: Blender draws the viewer at
  navigation @ base pose @ tracked pose, so a world-space transform applied on the left of the
  navigation moves the viewer by exactly that transform), and reset view resets the navigation
  as Blender's ``wm.xr_navigation_reset`` does (origin, no rotation, scale 1). Outside VR
  nothing changes. The functions take the session state as a value (``vr_orbit``,
  ``vr_zoom``, ``vr_reset``), so anything with those attribute names drives them.
"""

from __future__ import annotations

import math
from dataclasses import dataclass
from pathlib import Path

import bpy
from mathutils import Matrix, Quaternion, Vector

from ...controllers.actions import Action, Edit
from .. import compat


class EditSkipped(Exception):  # noqa: N818 - a message for the status line, not a failure
    """The action has nothing to act on here (no BTF material, no World...): say so, go on."""


@dataclass
class ViewState:
    """What RESET_VIEW restores: the camera's matrix and/or the viewport's view."""

    camera_matrix: Matrix | None = None
    view: tuple | None = None  # (view_location, view_rotation, view_distance)


class EditContext:
    """Where edits land. Holds the scene and view layer by name and looks them up on every
    use: an undo (Ctrl+Z during a session) reloads the data and would leave stored
    references dangling. The view (``region_3d``, ``region``) is set again by the operator
    before every poll (``set_view``): the user may close the area it belongs to at any time."""

    def __init__(self, scene, view_layer, region_3d=None, region=None) -> None:
        self.scene_name = scene.name
        self.view_layer_name = view_layer.name
        self.region_3d = region_3d  # a SpaceView3D's RegionView3D, None headless
        self.region = region  # its WINDOW region (for pointer rays), None headless
        self.has_view = region_3d is not None  # started in a 3D view: view edits need one
        self.target: str | None = None  # the object the current edit acts on, by name
        self.saved_view = ViewState()
        self.help_visible = False
        self.screenshots: list[str] = []
        # Where the VR session state comes from: None = Blender's window manager, looked up on
        # every edit (a VR session may start or stop during a Wiimote session); a callable
        # returning a stand-in state (or None) otherwise.
        self.xr_source = None

    def xr(self):
        """The running VR session's state (an XrSessionState), or None outside VR."""
        if self.xr_source is not None:
            return self.xr_source()
        return running_xr_state()

    def set_view(self, region_3d, region) -> None:
        """The 3D view as it is now (None, None: gone; the view edits then skip)."""
        self.region_3d, self.region = region_3d, region

    def view(self):
        """The RegionView3D the view edits act on; None headless (they use the scene camera).
        EditSkipped when the session's 3D view is gone."""
        if self.region_3d is None and self.has_view:
            raise EditSkipped("the 3D view is gone (open one to use the view controls)")
        return self.region_3d

    @property
    def scene(self):
        return bpy.data.scenes[self.scene_name]

    @property
    def view_layer(self):
        return self.scene.view_layers[self.view_layer_name]

    def save_view(self) -> None:
        camera = self.scene.camera
        self.saved_view = ViewState(
            camera.matrix_world.copy() if camera else None,
            (
                self.region_3d.view_location.copy(),
                self.region_3d.view_rotation.copy(),
                self.region_3d.view_distance,
            )
            if self.region_3d
            else None,
        )


def running_xr_state(context=None):
    """The window manager's XrSessionState while a VR session runs, else None (also in a build
    without OpenXR, and headless)."""
    context = context or bpy.context
    wm = getattr(context, "window_manager", None)
    state = getattr(wm, "xr_session_state", None) if wm is not None else None
    if state is None:
        return None
    try:
        return state if bpy.types.XrSessionState.is_running(context) else None
    except (AttributeError, RuntimeError, TypeError):  # no window context to ask in
        return None


# ------------------------------------------------------------------ materials
def btf_materials() -> list:
    return sorted((m for m in bpy.data.materials if m.btf.enabled), key=lambda m: m.name)


def _target_object(ctx: EditContext):
    """The object an edit acts on: the pointed-at one (``ctx.target``), else the active one."""
    if ctx.target is not None:
        obj = bpy.data.objects.get(ctx.target)
        if obj is not None:
            return obj
    return ctx.view_layer.objects.active


def _active_object(ctx: EditContext):
    obj = _target_object(ctx)
    if obj is None:
        raise EditSkipped("no active object")
    return obj


def sibling_sources(source: str) -> list[str]:
    """BTF sources beside ``source`` (folders and .btfm files in its parent), sorted."""
    path = Path(bpy.path.abspath(source))
    parent = path.parent
    if not parent.is_dir():
        return []
    found = [p for p in parent.iterdir() if p.is_dir() or p.suffix.lower() == ".btfm"]
    return sorted(str(p) for p in found)


def step_material(ctx: EditContext, step: int) -> str:
    obj = _active_object(ctx)
    if not obj.material_slots:
        raise EditSkipped(f"{obj.name!r} has no material slots")
    slot = obj.material_slots[obj.active_material_index]
    materials = btf_materials()
    if len(materials) >= 2:
        current = materials.index(slot.material) if slot.material in materials else -1
        new = materials[(current + step) % len(materials)]
        slot.material = new
        return f"material {new.name}"
    material = slot.material
    if material is None or not material.btf.enabled or not material.btf.source:
        raise EditSkipped("no other BTF material to switch to")
    sources = sibling_sources(material.btf.source)
    here = str(Path(bpy.path.abspath(material.btf.source)))
    if len(sources) < 2 or here not in sources:
        raise EditSkipped("no other BTF material or source beside this one")
    material.btf.source = sources[(sources.index(here) + step) % len(sources)]
    return f"source {Path(material.btf.source).name}"


def exposure_materials(ctx: EditContext) -> list:
    """The BTF material(s) exposure acts on: the active object's (its active slot first), or,
    without an active object with one, every BTF material of the view layer's objects."""
    obj = _target_object(ctx)
    if obj is not None:
        mat = obj.active_material
        if mat is not None and mat.btf.enabled:
            return [mat]
        for slot in obj.material_slots:
            if slot.material is not None and slot.material.btf.enabled:
                return [slot.material]
    found = {
        slot.material.name: slot.material
        for o in ctx.view_layer.objects
        for slot in o.material_slots
        if slot.material is not None and slot.material.btf.enabled
    }
    if not found:
        raise EditSkipped("no BTF material in view")
    return [found[name] for name in sorted(found)]


# -------------------------------------------------------------------- objects
def next_object(ctx: EditContext) -> str:
    meshes = sorted((o for o in ctx.view_layer.objects if o.type == "MESH"), key=lambda o: o.name)
    if not meshes:
        raise EditSkipped("no mesh objects")
    active = ctx.view_layer.objects.active
    new = meshes[(meshes.index(active) + 1) % len(meshes)] if active in meshes else meshes[0]
    for o in meshes:
        o.select_set(o == new)
    ctx.view_layer.objects.active = new
    return f"object {new.name}"


def _rotation_about(pivot: Vector, angle_rad: float, axis: Vector) -> Matrix:
    return (
        Matrix.Translation(pivot) @ Matrix.Rotation(angle_rad, 4, axis) @ Matrix.Translation(-pivot)
    )


def rotate_object(ctx: EditContext, degrees: float, axis: str) -> None:
    obj = _active_object(ctx)
    world_axis = Vector((0.0, 0.0, 1.0)) if axis != "X" else Vector((1.0, 0.0, 0.0))
    pivot = obj.matrix_world.translation.copy()
    obj.matrix_world = _rotation_about(pivot, math.radians(degrees), world_axis) @ obj.matrix_world


# ---------------------------------------------------------------- environment
def world_mapping(scene):
    """The World's Mapping node feeding its Environment Texture. An unlinked texture Vector
    gets Texture Coordinate (Generated) → Mapping inserted, which looks the same (Generated is
    the direction for a World) and is what ``export/world.py`` reads. EditSkipped when there is
    no Environment Texture, or its Vector comes from something else."""
    world = scene.world
    if world is None or world.node_tree is None:
        raise EditSkipped("the scene has no World nodes to rotate")
    if compat.world_nodes_switched_off(world):  # the exporter reads World.color, not the nodes
        raise EditSkipped("the World's nodes are switched off (turn on Use Nodes to rotate it)")
    tree = world.node_tree
    for node in tree.nodes:
        if node.bl_idname != "ShaderNodeTexEnvironment":
            continue
        vector = node.inputs["Vector"]
        if not vector.is_linked:
            coords = tree.nodes.new("ShaderNodeTexCoord")
            mapping = tree.nodes.new("ShaderNodeMapping")
            coords.location = (node.location.x - 400, node.location.y)
            mapping.location = (node.location.x - 200, node.location.y)
            tree.links.new(coords.outputs["Generated"], mapping.inputs["Vector"])
            tree.links.new(mapping.outputs["Vector"], vector)
            return mapping
        source = vector.links[0].from_node
        if source.bl_idname == "ShaderNodeMapping":
            return source
        raise EditSkipped(f"the Environment Texture's vector comes from {source.bl_label!r}")
    raise EditSkipped("the World has no Environment Texture")


def rotate_environment(ctx: EditContext, degrees: float) -> None:
    mapping = world_mapping(ctx.scene)
    sign = -1.0 if mapping.vector_type == "TEXTURE" else 1.0  # TEXTURE is the inverse map
    rotation = mapping.inputs["Rotation"]
    x, y, z = rotation.default_value
    rotation.default_value = (x, y, z + sign * math.radians(degrees))


# ------------------------------------------------------------------- view
def _pivot(ctx: EditContext) -> Vector:
    obj = ctx.view_layer.objects.active
    return obj.matrix_world.translation.copy() if obj is not None else Vector()


def orbit(ctx: EditContext, degrees: float, axis: str) -> None:
    angle = math.radians(degrees)
    r3d = ctx.view()
    if r3d is not None:
        if axis == "YAW":
            # The eye sits at view_rotation @ (0, 0, distance): turning it by +angle about Z
            # moves the eye to its right, as the camera below.
            r3d.view_rotation = Quaternion((0.0, 0.0, 1.0), angle) @ r3d.view_rotation
        else:
            right = r3d.view_rotation @ Vector((1.0, 0.0, 0.0))
            r3d.view_rotation = Quaternion(right, -angle) @ r3d.view_rotation  # up: eye up
        return
    camera = ctx.scene.camera
    if camera is None:
        raise EditSkipped("no scene camera to orbit")
    if axis == "YAW":
        world_axis = Vector((0.0, 0.0, 1.0))  # +angle: the camera moves to its right
    else:  # about the camera's right axis; +angle (stick up) lifts the camera
        world_axis = camera.matrix_world.to_3x3() @ Vector((1.0, 0.0, 0.0))
        angle = -angle
    camera.matrix_world = _rotation_about(_pivot(ctx), angle, world_axis) @ camera.matrix_world


def zoom(ctx: EditContext, stops: float) -> None:
    """``stops`` > 0 zooms in: the distance to the pivot is divided by 2**stops."""
    factor = 2.0 ** (-stops)
    r3d = ctx.view()
    if r3d is not None:
        r3d.view_distance = max(1e-3, r3d.view_distance * factor)
        return
    camera = ctx.scene.camera
    if camera is None:
        raise EditSkipped("no scene camera to zoom")
    pivot = _pivot(ctx)
    offset = camera.matrix_world.translation - pivot
    if offset.length * factor < 1e-3:
        raise EditSkipped("the camera is at the pivot")
    camera.matrix_world.translation = pivot + offset * factor


# --------------------------------------------------------------- VR navigation
def _navigation_about(xr_state, pivot: Vector, rotation: Quaternion, scale: float) -> None:
    """Apply the world-space transform "scale by ``scale`` and rotate by ``rotation`` about
    ``pivot``" to the VR viewer: left-multiplied onto the navigation matrix
    T(location) R(rotation) S(scale), it gives location' = pivot + rotation·scale·(location −
    pivot), rotation' = rotation·rotation₀, scale' = scale·scale₀ (a uniform scale commutes with
    the rotation)."""
    location = Vector(xr_state.navigation_location)
    nav_rotation = Quaternion(xr_state.navigation_rotation)
    offset = rotation @ (location - pivot)
    xr_state.navigation_location = pivot + offset * scale
    xr_state.navigation_rotation = rotation @ nav_rotation
    xr_state.navigation_scale = xr_state.navigation_scale * scale


def vr_orbit(xr_state, pivot, degrees: float, axis: str) -> None:
    """Orbit the VR viewer about ``pivot``: ``YAW`` about world Z (+: the viewer moves to its
    right, as the desktop orbit), ``PITCH`` about the horizontal axis to the viewer's right
    (+: the viewer rises). The horizon tilts with a pitch orbit; reset view levels it again."""
    angle = math.radians(degrees)
    if axis == "YAW":
        rotation = Quaternion((0.0, 0.0, 1.0), angle)
    else:
        right = Quaternion(xr_state.viewer_pose_rotation) @ Vector((1.0, 0.0, 0.0))
        right.z = 0.0
        if right.length < 1e-6:  # looking straight up or down: no horizontal right axis
            raise EditSkipped("looking straight up or down: no axis to orbit about")
        rotation = Quaternion(right.normalized(), -angle)
    _navigation_about(xr_state, Vector(pivot), rotation, 1.0)


#: navigation_scale is kept within these (Blender's RNA has no limit; a scale near zero or huge
#: makes the clip range useless).
VR_SCALE_RANGE = (1e-3, 1e3)


def vr_zoom(xr_state, pivot, stops: float) -> None:
    """Zoom the VR view towards ``pivot``: ``stops`` > 0 divides the viewer's distance to the
    pivot and its scale (navigation_scale) by 2**stops, so the pivot keeps its place in view
    and everything looks 2**stops times larger, with the stereo depth to match."""
    factor = 2.0 ** (-stops)
    new_scale = xr_state.navigation_scale * factor
    if not VR_SCALE_RANGE[0] <= new_scale <= VR_SCALE_RANGE[1]:
        raise EditSkipped(f"VR scale {new_scale:.3g} would leave {VR_SCALE_RANGE}")
    _navigation_about(xr_state, Vector(pivot), Quaternion(), factor)


def vr_reset(xr_state) -> None:
    """Reset the VR navigation (as ``wm.xr_navigation_reset``): the viewer back at its base
    pose (the scene camera or the session's landmark)."""
    xr_state.navigation_location = (0.0, 0.0, 0.0)
    xr_state.navigation_rotation = (1.0, 0.0, 0.0, 0.0)
    xr_state.navigation_scale = 1.0


def reset_view(ctx: EditContext) -> None:
    saved = ctx.saved_view
    r3d = ctx.view()
    if saved.camera_matrix is not None and ctx.scene.camera is not None:
        ctx.scene.camera.matrix_world = saved.camera_matrix
    if saved.view is not None and r3d is not None:
        location, rotation, distance = saved.view
        r3d.view_location = location
        r3d.view_rotation = rotation
        r3d.view_distance = distance


def screenshot(ctx: EditContext) -> str:
    if bpy.app.background:
        raise EditSkipped("no window to take a screenshot of (background mode)")
    folder = (
        Path(bpy.app.tempdir or ".") if not bpy.data.filepath else Path(bpy.data.filepath).parent
    )
    path = folder / f"btf_wiimote_{len(ctx.screenshots) + 1:03d}.png"
    bpy.ops.screen.screenshot(filepath=str(path))
    ctx.screenshots.append(str(path))
    return f"screenshot {path}"


# --------------------------------------------------------------------- entry
def lights_range(settings, name: str = "lights_per_redraw") -> tuple[int, int]:
    """The limits of ``settings.<name>`` as the property declares them (soft max where it
    has one: the panel's slider end)."""
    prop = settings.bl_rna.properties[name]
    high = prop.soft_max if prop.soft_max < prop.hard_max else prop.hard_max
    return prop.hard_min, high


def step_lights(ctx: EditContext, step: int) -> str:
    """Lights per frame of the display being looked at: in Blender's VR session the headset's
    (``scene.btf_vr``: its fixed count, switched from the frame budget, whose K the user can
    no longer steer by hand), else the viewport's lights per redraw (``scene.btf_render``)."""
    vr = getattr(ctx.scene, "btf_vr", None)
    if vr is not None and ctx.xr() is not None:
        low, high = lights_range(vr, "lights_per_frame")
        vr.lights_mode = "FIXED"
        vr.lights_per_frame = min(high, max(low, vr.lights_per_frame + step))
        return f"VR lights per frame {vr.lights_per_frame} (fixed)"
    settings = ctx.scene.btf_render
    low, high = lights_range(settings)
    settings.lights_per_redraw = min(high, max(low, settings.lights_per_redraw + step))
    return f"lights per redraw {settings.lights_per_redraw}"


def apply_edit(ctx: EditContext, edit: Edit) -> str:
    """Apply one edit to the scene; returns a short description for the status line. Raises
    EditSkipped when there is nothing to act on. Gesture ends (``edit.end``) change nothing."""
    if edit.end:
        return ""
    a, amount, settings = edit.action, edit.amount, ctx.scene.btf_render
    if a in (Action.NEXT_MATERIAL, Action.PREVIOUS_MATERIAL):
        return step_material(ctx, 1 if a is Action.NEXT_MATERIAL else -1)
    if a is Action.NEXT_OBJECT:
        return next_object(ctx)
    if a is Action.ROTATE_OBJECT:
        rotate_object(ctx, amount, edit.axis)
    elif a is Action.ROTATE_ENVIRONMENT:
        rotate_environment(ctx, amount)
    elif (
        a in (Action.ORBIT_CAMERA, Action.ZOOM_IN, Action.ZOOM_OUT, Action.RESET_VIEW)
        and (xr_state := ctx.xr()) is not None
    ):
        return _apply_vr_view(ctx, xr_state, edit)
    elif a is Action.ORBIT_CAMERA:
        orbit(ctx, amount, edit.axis)
    elif a in (Action.ZOOM_IN, Action.ZOOM_OUT):
        zoom(ctx, amount if a is Action.ZOOM_IN else -amount)
    elif a in (Action.LIGHTS_MORE, Action.LIGHTS_FEWER):
        return step_lights(ctx, round(amount) * (1 if a is Action.LIGHTS_MORE else -1))
    elif a in (Action.EXPOSURE_UP, Action.EXPOSURE_DOWN):
        materials = exposure_materials(ctx)
        for material in materials:
            material.btf.exposure += amount if a is Action.EXPOSURE_UP else -amount
        names = ", ".join(m.name for m in materials)
        return f"exposure {materials[0].btf.exposure:+.2f} ({names})"
    elif a is Action.PROGRESSIVE_TOGGLE:
        settings.progressive = not settings.progressive
        return f"progressive {'on' if settings.progressive else 'off'}"
    elif a is Action.HELP_TOGGLE:
        ctx.help_visible = not ctx.help_visible
        return f"help {'shown' if ctx.help_visible else 'hidden'}"
    elif a is Action.SCREENSHOT:
        return screenshot(ctx)
    elif a is Action.RESET_VIEW:
        reset_view(ctx)
        return "view reset"
    return ""


def _apply_vr_view(ctx: EditContext, xr_state, edit: Edit) -> str:
    """The view actions in a running VR session: they move the VR navigation."""
    a = edit.action
    if a is Action.RESET_VIEW:
        vr_reset(xr_state)
        return "VR navigation reset"
    if a is Action.ORBIT_CAMERA:
        vr_orbit(xr_state, _pivot(ctx), edit.amount, edit.axis)
    else:
        vr_zoom(xr_state, _pivot(ctx), edit.amount if a is Action.ZOOM_IN else -edit.amount)
    return ""
