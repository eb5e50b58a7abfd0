"""The object under a pointer: a ray through a point of the view (the Wiimote's IR pointer,
(x, y) in −1..1) from the 3D viewport, or headless from the scene camera's frame; in a running
VR session also the object under the headset's gaze and under a controller's aim.

VR poses (Blender's ``XrSessionState.viewer_pose_*`` and ``XrEventData.controller_*``) are in
world space, navigation included; a pose looks along its own −Z (OpenXR's convention for views
and aim poses, and the axis Blender's own XR ray casts use, ``wm_xr_operators.cc``).
"""

from __future__ import annotations

import bpy
from mathutils import Quaternion, Vector

#: The forward axis of a VR pose in its own frame.
POSE_FORWARD = (0.0, 0.0, -1.0)


def pointer_ray(ctx, pointer: tuple[float, float]) -> tuple[Vector, Vector] | None:
    """(origin, direction) in world space through ``pointer`` ((x, y) in −1..1 of the view):
    the 3D viewport's view when there is one, else the scene camera's frame. EditSkipped when
    the session's 3D view is gone (``ctx.view()``)."""
    if ctx.view() is not None and ctx.region is not None:
        from bpy_extras import view3d_utils

        xy = ((pointer[0] + 1) / 2 * ctx.region.width, (pointer[1] + 1) / 2 * ctx.region.height)
        origin = view3d_utils.region_2d_to_origin_3d(ctx.region, ctx.region_3d, xy)
        return origin, view3d_utils.region_2d_to_vector_3d(ctx.region, ctx.region_3d, xy)
    camera = ctx.scene.camera
    if camera is None:
        return None
    # view_frame: the frame's corners in camera space (top right, bottom right, bottom left,
    # top left) on the plane z = −1 for a perspective camera.
    corners = camera.data.view_frame(scene=ctx.scene)
    right, top = corners[0].x, corners[0].y
    left, bottom = corners[2].x, corners[2].y
    x = left + (pointer[0] + 1) / 2 * (right - left)
    y = bottom + (pointer[1] + 1) / 2 * (top - bottom)
    world = camera.matrix_world
    if camera.data.type == "ORTHO":
        return world @ Vector((x, y, 0.0)), world.to_3x3() @ Vector((0.0, 0.0, -1.0))
    return world.translation.copy(), (world.to_3x3() @ Vector((x, y, corners[0].z))).normalized()


def object_under_pointer(ctx, pointer: tuple[float, float]) -> str | None:
    """The name of the first object the pointer's ray hits, or None."""
    ray = pointer_ray(ctx, pointer)
    if ray is None:
        return None
    return object_along_ray(ctx.scene, *ray)


def pose_ray(location, rotation) -> tuple[Vector, Vector]:
    """(origin, unit direction) in world space of a VR pose: ``location`` (3 floats) and
    ``rotation`` (a quaternion, 4 floats w, x, y, z) looking along the pose's −Z."""
    direction = Quaternion(rotation) @ Vector(POSE_FORWARD)
    return Vector(location), direction.normalized()


def gaze_ray(xr_state) -> tuple[Vector, Vector]:
    """The headset's gaze: a ray from ``viewer_pose_location`` along the viewer's −Z.
    ``xr_state``: an XrSessionState (or anything with those two attributes)."""
    return pose_ray(xr_state.viewer_pose_location, xr_state.viewer_pose_rotation)


def object_along_ray(scene, origin, direction) -> str | None:
    """The name of the first object the ray hits in ``scene`` (evaluated), or None."""
    depsgraph = bpy.context.evaluated_depsgraph_get()
    hit, _, _, _, obj, _ = scene.ray_cast(depsgraph, Vector(origin), Vector(direction))
    return obj.original.name if hit and obj is not None else None


def object_under_gaze(scene, xr_state) -> str | None:
    """The object the headset looks at (the centre of the view), or None."""
    return object_along_ray(scene, *gaze_ray(xr_state))


def object_under_aim(scene, location, rotation) -> str | None:
    """The object a VR controller points at (its aim pose), or None."""
    return object_along_ray(scene, *pose_ray(location, rotation))
