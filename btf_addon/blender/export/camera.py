"""The scene's active camera → ``scene.scene.Camera`` (Blender's frustum, sensor fit, shift)."""

from __future__ import annotations

import logging
import math

import numpy as np

from ...core.errors import BTFError
from ...scene.scene import Camera

log = logging.getLogger(__name__)


def fits_width(sensor_fit: str, aspect: float) -> bool:
    """Whether the sensor's size applies to the image's width (Blender's ``sensor_fit``: AUTO
    fits the larger side)."""
    if sensor_fit == "AUTO":
        return aspect >= 1
    return sensor_fit == "HORIZONTAL"


def export_camera(
    scene,
    width: int,
    height: int,
    view: tuple[np.ndarray, float] | None = None,
    depsgraph=None,
) -> Camera:
    """``scene.camera`` seen at ``width`` × ``height`` pixels. Raises BTFError without one.
    ``view``: one view of a stereo camera, as Blender's render engine gives it (its model
    matrix and horizontal shift, ``RenderEngine.camera_model_matrix``/``camera_shift_x``).
    ``depsgraph``: the camera as evaluated there — a scene Blender renders without evaluating
    its originals (the material preview, ``render.render(scene=…)``) has an original camera at
    the origin."""
    cam_obj = scene.camera
    if cam_obj is None:
        raise BTFError("the scene has no camera: add one (Add > Camera) and make it active")
    if depsgraph is not None:
        cam_obj = cam_obj.evaluated_get(depsgraph)
    cam = cam_obj.data
    matrix, shift_x = view if view is not None else (cam_obj.matrix_world, cam.shift_x)
    m = np.array(matrix, dtype=np.float64)
    m[:3, :3] /= np.linalg.norm(m[:3, :3], axis=0)  # drop object scale: a camera has none
    aspect = width / height
    horizontal = fits_width(cam.sensor_fit, aspect)
    # AUTO measures the larger side with sensor_width, whichever side that is.
    sensor = cam.sensor_width if horizontal or cam.sensor_fit == "AUTO" else cam.sensor_height
    # Blender measures shift in units of the sensor-fit dimension; Camera in the larger one.
    shift_factor = (aspect if horizontal else 1.0) / max(aspect, 1.0)
    shift = (shift_x * shift_factor, cam.shift_y * shift_factor)
    if cam.type == "ORTHO":
        larger = (
            cam.ortho_scale
            if horizontal == (aspect >= 1)
            else (cam.ortho_scale / aspect if aspect >= 1 else cam.ortho_scale * aspect)
        )
        return Camera(
            m,
            perspective=False,
            ortho_scale=larger,
            clip_start=cam.clip_start,
            clip_end=cam.clip_end,
            shift=shift,
        )
    half = sensor / 2 / cam.lens
    half_h = half / aspect if horizontal else half
    if cam.type != "PERSP":
        log.warning("panoramic cameras are drawn as perspective")
    return Camera(
        m,
        True,
        2 * math.atan(half_h),
        clip_start=cam.clip_start,
        clip_end=cam.clip_end,
        shift=shift,
    )
