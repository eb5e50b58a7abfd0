"""The progressive drawer (gl/drawer.py) on moderngl: several views over one drawer's scene
resources, uploads handed from one drawer to the next, misuse refused."""

from __future__ import annotations

from dataclasses import replace

import numpy as np
import pytest

from btf_addon.core.codecs.analytic import GGXBTF, LambertianBTF
from btf_addon.core.sampling.envmap import Environment
from btf_addon.scene.lights import PointLight
from btf_addon.scene.primitives import plane, uv_sphere
from btf_addon.scene.scene import Camera, Material, Scene, look_at

W, H = 64, 48


def two_material_scene(rng) -> Scene:
    """A GGX sphere on a Lambertian ground, a point light, a random environment."""
    ground = plane(8.0, uv_repeats=4.0, material=1)
    ground.world_from_object = np.eye(4)
    ground.world_from_object[2, 3] = -1.0
    return Scene(
        [uv_sphere(1.0, segments=32, rings=16), ground],
        [Material(GGXBTF((0.9, 0.6, 0.3), 0.4)), Material(LambertianBTF(0.5), exposure=0.5)],
        Camera(look_at((0.0, -4.0, 0.5), (0.0, 0.0, 0.0))),
        Environment(rng.gamma(0.7, 1.0, size=(16, 32, 3))),
        lights=[PointLight(np.array([2.0, -2.0, 2.0]), np.array([20.0, 15.0, 10.0]))],
    )


def eye(x: float) -> Camera:
    return Camera(look_at((x, -4.0, 0.5), (0.0, 0.0, 0.0)), fov_y_rad=np.radians(50))


def restart(drawer, view, camera: Camera) -> None:
    drawer.restart(view, camera.clip_from_world(view.width / view.height), camera.shader_vector())


def image(drawer, view) -> np.ndarray:
    drawer.resolve(view)
    return view.read()[::-1, :, :3]


def test_two_views_of_one_drawer_accumulate_independently(gl_ctx, rng):
    """Two eyes, each with its own lights, batch size and camera, drawn interleaved over one
    drawer's uploads (and one restarted halfway): each equals a single-view render of its own
    camera. Same GL operations in the same order per view → the same pixels, bit for bit."""
    from btf_addon.gl.drawer import ProgressiveDrawer, ViewAccumulation
    from btf_addon.gl.moderngl_device import ModernGLDevice
    from btf_addon.gl.renderer import GLSLRenderer

    scene = two_material_scene(rng)
    left, right = eye(-0.6), eye(0.6)
    left_lights = scene.environment.virtual_lights(20, seed=1)
    right_lights = scene.environment.virtual_lights(12, seed=2)
    device = ModernGLDevice(gl_ctx)
    drawer = ProgressiveDrawer(device, scene)
    views = [ViewAccumulation(device, W, H), ViewAccumulation(device, W, H)]
    try:
        views[0].set_lights(left_lights, per_pass=6)  # 6 + 6 + 6 + 2
        views[1].set_lights(right_lights, per_pass=5)  # 5 + 5 + 2
        restart(drawer, views[0], left)
        restart(drawer, views[1], right)
        drawer.add_batch(views[0])
        drawer.add_batch(views[1])
        drawer.add_batch(views[0])
        restart(drawer, views[0], left)  # one eye restarts: the other keeps its 5 lights
        assert views[0].state.done == 0 and views[1].state.done == 5
        while drawer.add_batch(views[0]) + drawer.add_batch(views[1]):
            pass
        assert views[0].state.converged and views[1].state.converged
        drawn = [image(drawer, v) for v in views]
    finally:
        for view in views:
            view.release()
        drawer.release()

    for camera, lights, per_pass, got in (
        (left, left_lights, 6, drawn[0]),
        (right, right_lights, 5, drawn[1]),
    ):
        single = GLSLRenderer(replace(scene, camera=camera), W, H, gl_ctx)
        try:
            expected = single.render(lights, per_pass=per_pass)
        finally:
            single.release()
        np.testing.assert_array_equal(got, expected)
    # The eyes see different images (else the test above proves nothing about the cameras).
    assert np.abs(drawn[0] - drawn[1]).mean() > 0.05 * drawn[1].mean()


def test_a_drawer_reuses_unchanged_uploads_of_the_previous(gl_ctx, rng):
    """One mesh moved: only its buffer is uploaded again; what is reused still draws (the
    previous drawer released only what nothing uses)."""
    from btf_addon.gl.drawer import ProgressiveDrawer, ViewAccumulation
    from btf_addon.gl.moderngl_device import ModernGLDevice

    scene = two_material_scene(rng)
    lights = scene.environment.virtual_lights(8, seed=3)
    device = ModernGLDevice(gl_ctx)
    first = ProgressiveDrawer(device, scene)
    tables, env_tex = list(first.tables), first.env_tex
    moved = replace(scene.meshes[0], world_from_object=np.eye(4))
    moved.world_from_object[0, 3] = 0.3
    edited = replace(scene, meshes=[moved, scene.meshes[1]])
    second = ProgressiveDrawer(device, edited, previous=first)
    fresh = ProgressiveDrawer(device, edited)
    view = ViewAccumulation(device, W, H)
    try:
        assert second.uploads == {"tables": 0, "meshes": 1}
        assert second.tables == tables and second.env_tex is env_tex
        images = []
        for drawer in (second, fresh):
            view.set_lights(lights, per_pass=8)
            restart(drawer, view, scene.camera)
            drawer.add_batch(view)
            images.append(image(drawer, view))
        np.testing.assert_array_equal(images[0], images[1])
        with pytest.raises(RuntimeError, match="handed over"):  # its uploads are second's now
            restart(first, view, scene.camera)
    finally:
        view.release()
        second.release()
        fresh.release()


def test_misuse_is_refused(gl_ctx, rng):
    from btf_addon.gl.drawer import ProgressiveDrawer, ViewAccumulation
    from btf_addon.gl.moderngl_device import ModernGLDevice

    device = ModernGLDevice(gl_ctx)
    scene = two_material_scene(rng)
    drawer = ProgressiveDrawer(device, scene)
    with pytest.raises(ValueError, match="outside"):
        ViewAccumulation(device, 0, 10)
    view = ViewAccumulation(device, 8, 8)
    try:
        with pytest.raises(RuntimeError, match="lights"):
            drawer.add_batch(view)
        view.set_lights(scene.environment.virtual_lights(4), per_pass=2)
        with pytest.raises(RuntimeError, match="restart"):  # lights changed, image did not
            drawer.add_batch(view)
        restart(drawer, view, scene.camera)
        assert drawer.add_batch(view) == 2
    finally:
        view.release()
        drawer.release()


def test_resolving_into_a_callers_framebuffer_equals_the_views_output(gl_ctx, rng):
    """``draw_resolved`` (an eye's framebuffer in a draw callback, a swapchain image) draws the
    pixels ``resolve`` puts into the view's own output."""
    from btf_addon.gl.drawer import ProgressiveDrawer, ViewAccumulation
    from btf_addon.gl.moderngl_device import ModernGLDevice

    device = ModernGLDevice(gl_ctx)
    scene = two_material_scene(rng)
    drawer = ProgressiveDrawer(device, scene)
    view = ViewAccumulation(device, W, H)
    swapchain_image = device.target(W, H, "RGBA32F", depth=False)
    try:
        view.set_lights(scene.environment.virtual_lights(6), per_pass=4)
        restart(drawer, view, scene.camera)
        drawer.add_batch(view)  # 4 of 6: the division by the lights so far is exercised
        drawer.resolve(view)
        with device.bound(swapchain_image):
            drawer.draw_resolved(view)
        own = view.read()
        assert own[..., :3].max() > 0.1
        np.testing.assert_array_equal(device.read(swapchain_image), own)
    finally:
        device.release(swapchain_image)
        view.release()
        drawer.release()


def test_renderers_on_two_contexts_draw_into_their_own(gl_ctx, rng):
    """moderngl sends calls to the current context; the adapter makes its own current for its
    work, so a renderer still draws the same image after a second context was created (and is
    current), and after that context is gone. (Without it: garbage from the other context.)"""
    from btf_addon.gl.renderer import GLSLRenderer

    scene = two_material_scene(rng)
    lights = scene.environment.virtual_lights(8, seed=1)
    first = GLSLRenderer(scene, W, H, gl_ctx)
    before = first.render(lights)
    second = GLSLRenderer(replace(scene, camera=eye(0.6)), 32, 24)  # its own context, current
    try:
        assert second.render(lights).max() > 0.1
        np.testing.assert_array_equal(first.render(lights), before)
    finally:
        second.release()
    np.testing.assert_array_equal(first.render(lights), before)
    first.release()  # makes the session context current again: later tests use it directly


def test_every_drawer_has_its_own_serial_even_at_a_reused_address(gl_ctx, rng):
    """Views key their lights and depth on the drawer that made them (the VR preview, the
    bridge): a drawer made after another was freed must not pass for it, as id() can."""
    from btf_addon.gl.drawer import ProgressiveDrawer
    from btf_addon.gl.moderngl_device import ModernGLDevice

    device = ModernGLDevice(gl_ctx)
    scene = two_material_scene(rng)
    serials, ids = set(), set()
    for _ in range(4):
        drawer = ProgressiveDrawer(device, scene)
        serials.add(drawer.serial)
        ids.add(id(drawer))
        drawer.release()
        del drawer
    assert len(serials) == 4  # (ids may repeat: CPython reuses a freed object's address)


def test_exposure_scales_each_material_by_its_own_block(gl_ctx, rng):
    """The exposure comes from each mesh's material block (as in the OpenCL kernels): +1 stop on
    one material doubles exactly its pixels (× 2 is exact in float) and leaves the other's."""
    from btf_addon.gl.renderer import GLSLRenderer

    scene = two_material_scene(rng)
    scene.lights = []  # Blender's lights are not under the exposure test here
    lights = scene.environment.virtual_lights(16, seed=3)
    base = GLSLRenderer(scene, W, H, gl_ctx).render(lights)
    scene.materials[0].exposure = 1.0
    brighter = GLSLRenderer(scene, W, H, gl_ctx).render(lights)
    changed = np.any(brighter != base, axis=-1)
    assert changed.sum() > 100  # the sphere
    np.testing.assert_array_equal(brighter[changed], 2.0 * base[changed])
    assert (~changed).sum() > 100 and base[~changed].max() > 0  # the ground kept its look


def test_meshes_of_one_material_are_drawn_in_one_draw(gl_ctx, rng):
    """A pass draws once per material, not once per mesh (Blender's VR session draws every eye
    of a scene of many objects): twelve spheres on two materials are two draws a pass, and the
    image equals the same scene drawn one mesh per material (twelve materials: twelve draws),
    each mesh reading its own block (exposure) from its vertices."""
    from btf_addon.gl.drawer import ProgressiveDrawer, ViewAccumulation
    from btf_addon.gl.moderngl_device import ModernGLDevice

    spheres = []
    for i in range(12):
        mesh = uv_sphere(0.3, segments=12, rings=6, material=i % 2)
        mesh.world_from_object = np.eye(4)
        mesh.world_from_object[:3, 3] = ((i % 4) - 1.5, 0.0, (i // 4) - 1.0)
        spheres.append(mesh)
    shared = [Material(GGXBTF((0.9, 0.6, 0.3), 0.4)), Material(LambertianBTF(0.5), exposure=0.5)]
    batched = Scene(
        spheres,
        shared,
        Camera(look_at((0.0, -5.0, 0.0), (0.0, 0.0, 0.0))),
        Environment(rng.gamma(0.7, 1.0, size=(16, 32, 3))),
    )
    # The same materials, one per mesh (the same BTF objects: equal tables).
    apart = replace(
        batched,
        meshes=[replace(m, material=i) for i, m in enumerate(spheres)],
        materials=[shared[i % 2] for i in range(12)],
    )
    lights = batched.environment.virtual_lights(8, seed=5)
    device = ModernGLDevice(gl_ctx)
    draws = []
    original = device.draw

    def counting(*args):
        draws.append(1)
        return original(*args)

    device.draw = counting
    view = ViewAccumulation(device, W, H)
    images, counts = [], []
    try:
        for scene in (batched, apart):
            drawer = ProgressiveDrawer(device, scene)
            view.set_lights(lights, per_pass=8)
            restart(drawer, view, scene.camera)
            draws.clear()
            drawer.add_batch(view)
            counts.append(len(draws))
            images.append(image(drawer, view))
            drawer.release()
    finally:
        view.release()
    assert counts == [2, 12]
    assert images[0].max() > 0
    # The same triangles and blocks in another order within a draw: equal up to the order
    # of the (associative only in exact arithmetic) per-light sums, which is the same per pixel.
    np.testing.assert_allclose(images[0], images[1], rtol=1e-6, atol=1e-7)
