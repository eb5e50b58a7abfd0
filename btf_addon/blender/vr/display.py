"""The scene's view transform on the eyes' image (issue 35 item 2): what Blender does to its own
eye image before our callback's is merged over it.

Blender's VR session runs our callback into its overlay buffer (8-bit, sRGB-encoded storage),
which ``GPU_viewport`` merges over its own image AFTER that image went through the scene's
OpenColorIO display transform (``intern/opencolorio/gpu_shader_display_transform_frag.glsl``
``OCIO_ProcessColor``): ``col = OCIO_to_display(scene_linear × 2^exposure)``, then, with an
overlay, ``col = pow(col, 2.2)``, ``col = col·(1 − overlay.a) + overlay``, ``col = pow(col,
1/2.2)``. A scene-linear image written there as it is skips the view transform (AgX, Filmic),
the Look, exposure and gamma, and is clamped to 0..1. So the eye's image is resolved into the
view's own float target and drawn into the overlay through ``DISPLAY_SHADER``: per pixel the
display value ``D`` of the scene's view transform (a 3D LUT of ``LUT_SIZE``³ nodes over a log2
shaper, baked by ``bake_lut``), written as ``D^2.2`` so that Blender's ``pow(·, 1/2.2)`` gives
back ``D``: the desktop's colour for the same radiance.

The LUT is baked by Blender itself: a float image of the LUT's scene-linear inputs saved with
``Image.save_render(scene=…)`` as an 8-bit PNG (display-referred: through the scene's display
device, view transform, Look, exposure and gamma, copied into a scene of our own whose output
is PNG whatever the user's is; curve mapping points are not copied), read back. That creates
and removes data blocks and writes a temporary file, which a draw callback must not do:
``DisplayTransform.update`` runs in handlers and timers (session start, depsgraph updates, a
timer the draw callback asks for when the scene's view settings no longer match the LUT); until
a LUT matches, the eyes are drawn untransformed as before.
"""

from __future__ import annotations

import os
import tempfile

import numpy as np

LUT_SIZE = 65  # nodes per axis: node 0 is 0, nodes 1.. cover LOG2_MIN..LOG2_MAX evenly in log2
LOG2_MIN, LOG2_MAX = -12.0, 10.0  # scene-linear 2^-12 .. 2^10 (beyond: clamped to the ends)
OVERLAY_GAMMA = 2.2  # Blender's overlay merge: pow(col, 2.2), blend, pow(col, 1 / 2.2)


def lut_inputs(n: int = LUT_SIZE) -> np.ndarray:
    """``(n,)`` float64: the scene-linear value at each node of one axis."""
    return np.concatenate([[0.0], np.exp2(np.linspace(LOG2_MIN, LOG2_MAX, n - 1))])


def lut_index(x: np.ndarray, n: int = LUT_SIZE) -> np.ndarray:
    """Scene-linear ``x`` → fractional node index in [0, n − 1] (the shader's ``lut_index``):
    linear between 0 and 2^LOG2_MIN, log2 above."""
    x = np.maximum(np.asarray(x, dtype=np.float64), 0.0)
    low = 2.0**LOG2_MIN
    step = (LOG2_MAX - LOG2_MIN) / (n - 2)
    with np.errstate(divide="ignore"):
        index = np.where(x <= low, x / low, 1.0 + (np.log2(np.maximum(x, low)) - LOG2_MIN) / step)
    return np.clip(index, 0.0, n - 1.0)


def apply_lut(lut: np.ndarray, rgb: np.ndarray) -> np.ndarray:
    """The numpy reference of the shader's lookup: ``lut`` ``(n, n, n, 3)`` indexed
    [b, g, r], ``rgb`` ``(..., 3)`` scene-linear → display values ``(..., 3)``, trilinear."""
    n = lut.shape[0]
    index = lut_index(rgb, n)
    i0 = np.minimum(np.floor(index).astype(int), n - 2)
    f = index - i0
    out = np.zeros((*rgb.shape[:-1], 3))
    for corner in range(8):
        d = [(corner >> axis) & 1 for axis in range(3)]  # r, g, b offsets
        w = np.prod([f[..., a] if d[a] else 1.0 - f[..., a] for a in range(3)], axis=0)
        out += w[..., None] * lut[i0[..., 2] + d[2], i0[..., 1] + d[1], i0[..., 0] + d[0]]
    return out


def view_key(scene) -> tuple:
    """What the display transform depends on: a new LUT when any of it changes."""
    view, display = scene.view_settings, scene.display_settings
    return (
        display.display_device,
        view.view_transform,
        view.look,
        round(float(view.exposure), 6),
        round(float(view.gamma), 6),
        bool(view.use_curve_mapping),
    )


def display_values(scene, rgb: np.ndarray) -> np.ndarray:
    """``rgb`` ``(N, 3)`` scene-linear → ``(N, 3)`` the display values Blender shows for them
    with ``scene``'s view settings (8-bit precision: a PNG through ``save_render``)."""
    import bpy

    rgb = np.asarray(rgb, dtype=np.float32).reshape(-1, 3)
    count = len(rgb)
    width = min(count, 4096)
    height = -(-count // width)
    pixels = np.ones((height * width, 4), dtype=np.float32)
    pixels[:count, :3] = rgb
    image = bpy.data.images.new("btf-vr-display-lut", width, height, float_buffer=True)
    handle, path = tempfile.mkstemp(prefix="btf-vr-display-", suffix=".png")
    os.close(handle)
    loaded = None
    # A scene of our own with the view settings of ``scene`` and an 8-bit PNG as its output
    # (the user's scene may save EXR, which is written without any view transform).
    settings_scene = bpy.data.scenes.new("btf-vr-display-settings")
    try:
        _copy_colour_management(scene, settings_scene)
        out_format = settings_scene.render.image_settings
        out_format.file_format, out_format.color_mode, out_format.color_depth = "PNG", "RGB", "8"
        image.pixels.foreach_set(pixels.ravel())
        image.save_render(path, scene=settings_scene)
        loaded = bpy.data.images.load(path, check_existing=False)
        out = np.empty(width * height * 4, dtype=np.float32)
        loaded.pixels.foreach_get(out)
    finally:
        bpy.data.scenes.remove(settings_scene)
        bpy.data.images.remove(image)
        if loaded is not None:
            bpy.data.images.remove(loaded)
        os.remove(path)
    return out.reshape(-1, 4)[:count, :3].astype(np.float64)


def _copy_colour_management(source, target) -> None:
    """``source``'s display device, then view settings (view transform before look: a look
    belongs to a view transform), into ``target``. Curve mapping points are not copied."""
    target.display_settings.display_device = source.display_settings.display_device
    view, into = source.view_settings, target.view_settings
    names = [p.identifier for p in view.bl_rna.properties if not p.is_readonly]
    names.sort(key=lambda name: (name != "view_transform", name != "look", name))
    for name in names:
        if name == "rna_type" or view.bl_rna.properties[name].type == "POINTER":
            continue
        try:
            setattr(into, name, getattr(view, name))
        except (TypeError, ValueError, AttributeError):  # a value the target refuses
            pass


def bake_lut(scene, n: int = LUT_SIZE) -> np.ndarray:
    """``(n, n, n, 3)`` float32 display values of ``scene``'s view transform, indexed [b, g, r]
    at ``lut_inputs(n)``: the 3D texture's layout (x = red fastest)."""
    axis = lut_inputs(n)
    b, g, r = np.meshgrid(axis, axis, axis, indexing="ij")
    rgb = np.stack([r, g, b], axis=-1).reshape(-1, 3)
    return display_values(scene, rgb).reshape(n, n, n, 3).astype(np.float32)


DISPLAY_VERTEX = """
void main()
{
  gl_Position = vec4(pos, 0.0, 1.0);
}
"""

DISPLAY_FRAGMENT = """
float lut_index(float x)
{
  float low = exp2(LOG2_MIN);
  float i = (x <= low) ? x / low : 1.0 + (log2(x) - LOG2_MIN) / LOG2_STEP;
  return clamp(i, 0.0, LUT_N - 1.0);
}

vec3 lut_fetch(ivec3 i)
{
  return texelFetch(lut, i, 0).rgb;
}

void main()
{
  vec4 c = texelFetch(image, ivec2(gl_FragCoord.xy), 0);
  float a = clamp(c.a, 0.0, 1.0);
  vec3 rgb = (a > 0.0) ? max(c.rgb / a, vec3(0.0)) : vec3(0.0);
  vec3 index = vec3(lut_index(rgb.r), lut_index(rgb.g), lut_index(rgb.b));
  ivec3 i0 = min(ivec3(floor(index)), ivec3(int(LUT_N) - 2));
  vec3 f = index - vec3(i0);
  vec3 c00 = mix(lut_fetch(i0), lut_fetch(i0 + ivec3(1, 0, 0)), f.x);
  vec3 c10 = mix(lut_fetch(i0 + ivec3(0, 1, 0)), lut_fetch(i0 + ivec3(1, 1, 0)), f.x);
  vec3 c01 = mix(lut_fetch(i0 + ivec3(0, 0, 1)), lut_fetch(i0 + ivec3(1, 0, 1)), f.x);
  vec3 c11 = mix(lut_fetch(i0 + ivec3(0, 1, 1)), lut_fetch(i0 + ivec3(1, 1, 1)), f.x);
  vec3 d = mix(mix(c00, c10, f.y), mix(c01, c11, f.y), f.z);
  frag_color = vec4(pow(clamp(d, 0.0, 1.0), vec3(OVERLAY_GAMMA)) * a, a);
}
"""


def _display_shader():
    import gpu

    info = gpu.types.GPUShaderCreateInfo()
    info.vertex_in(0, "VEC2", "pos")
    info.fragment_out(0, "VEC4", "frag_color")
    info.sampler(0, "FLOAT_2D", "image")
    info.sampler(1, "FLOAT_3D", "lut")
    info.define("LUT_N", f"{float(LUT_SIZE)}")
    info.define("LOG2_MIN", f"{LOG2_MIN}")
    info.define("LOG2_STEP", f"{(LOG2_MAX - LOG2_MIN) / (LUT_SIZE - 2)}")
    info.define("OVERLAY_GAMMA", f"{OVERLAY_GAMMA}")
    info.vertex_source(DISPLAY_VERTEX)
    info.fragment_source(DISPLAY_FRAGMENT)
    return gpu.shader.create_from_info(info)


class DisplayTransform:
    """The scene's view transform as a LUT (``update`` outside drawing) and its GPU pass
    (``draw`` inside the callback). ``key``: the view settings the LUT was baked for."""

    def __init__(self) -> None:
        self.key: tuple | None = None
        self.lut: np.ndarray | None = None
        self.bakes = 0
        self._texture = self._shader = self._batch = None

    def matches(self, scene) -> bool:
        return self.lut is not None and self.key == view_key(scene)

    def update(self, scene) -> None:
        """Bake the LUT again if ``scene``'s view settings changed (not from a draw callback:
        it adds and removes data blocks and writes a temporary file)."""
        key = view_key(scene)
        if key == self.key and self.lut is not None:
            return
        self.lut, self.key = bake_lut(scene), key
        self._texture = None
        self.bakes += 1

    def draw(self, image_texture) -> None:
        """Into the BOUND framebuffer (blend state set by the caller): ``image_texture``
        (premultiplied scene-linear, the eye's size) through the LUT, encoded for Blender's
        overlay merge."""
        import gpu
        from gpu_extras.batch import batch_for_shader

        if self._shader is None:
            self._shader = _display_shader()
            self._batch = batch_for_shader(
                self._shader, "TRIS", {"pos": [(-1.0, -1.0), (3.0, -1.0), (-1.0, 3.0)]}
            )
        if self._texture is None:
            n = self.lut.shape[0]
            rgba = np.ones((n, n, n, 4), dtype=np.float32)
            rgba[..., :3] = self.lut
            data = gpu.types.Buffer("FLOAT", rgba.size, rgba.ravel())
            self._texture = gpu.types.GPUTexture((n, n, n), format="RGBA32F", data=data)
        self._shader.bind()
        self._shader.uniform_sampler("image", image_texture)
        self._shader.uniform_sampler("lut", self._texture)
        self._batch.draw(self._shader)

    def release(self) -> None:
        self._texture = self._shader = self._batch = None
