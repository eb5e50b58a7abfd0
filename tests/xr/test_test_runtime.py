"""The OpenXR test runtime (tests/xr_runtime), driven through the REAL OpenXR loader with
pyopenxr and a surfaceless EGL OpenGL context, as any GL app would drive a headset runtime.

What is checked is the runtime's own contract (docs/development.md "The OpenXR test runtime"):
the simulated HMD, the session state machine, the frame loop, the capture, and the faults.
"""

from __future__ import annotations

import ctypes
import os
import time

import numpy as np
import pytest
from xr_runtime.build import LIBRARY_NAME, RuntimeBuildError, build_runtime, missing_tools
from xr_runtime.readback import srgb_to_linear

xr = pytest.importorskip("xr", reason="pyopenxr is in requirements/common.txt")

from xr_runtime.client import (  # noqa: E402
    EXTENSIONS,
    GL_RGBA8,
    GL_RGBA16F,
    GL_RGBA32F,
    GL_SRGB8_ALPHA8,
    STEREO,
    App,
    quat_rotate,
    start_running,
    submit_frame,
)
from xr_runtime.egl import EGLError  # noqa: E402

S = xr.SessionState
# sRGB8 stores 8 bits after encoding: half a step (0.5/255) in encoded units is at most
# 0.5/255 * d(decode)/dv <= 0.5/255 * 2.4/1.055 * 1 ~= 0.0045 in linear units (slope max at 1).
SRGB8_TOL = 0.005
RGBA16F_TOL = 1e-3  # half floats: 11-bit mantissa, relative error 2^-11 ~ 5e-4 below 1.0
GL_RGBA8UI = 0x8D7C  # an integer format: glGetTexImage(GL_RGBA, GL_FLOAT) cannot read it


class SkippingApp(App):
    def start(self, requirements=True):
        try:
            return super().start(requirements)
        except EGLError as exc:
            pytest.skip(f"no surfaceless EGL OpenGL here ({exc})")


@pytest.fixture
def app_factory():
    """Makes Apps; closes them (session, context, instance) after the test."""
    apps = []

    def make(**kwargs):
        apps.append(SkippingApp(**kwargs))
        return apps[-1]

    yield make
    for app in apps:
        app.close()


# ---------------------------------------------------------------------------------------------
# building
# ---------------------------------------------------------------------------------------------
def test_runtime_builds_from_a_clean_dir_and_only_rebuilds_when_a_source_changes(tmp_path):
    manifest = build_runtime(tmp_path / "clean")
    library = tmp_path / "clean" / LIBRARY_NAME
    import json

    data = json.loads(manifest.read_text())
    assert data["file_format_version"] == "1.0.0"
    assert data["runtime"]["library_path"] == str(library)
    assert os.path.isabs(data["runtime"]["library_path"])
    built = library.stat().st_mtime_ns
    time.sleep(0.01)
    build_runtime(tmp_path / "clean")
    assert library.stat().st_mtime_ns == built  # up to date: not recompiled
    # a library older than the sources is rebuilt
    os.utime(library, ns=(1, 1))
    build_runtime(tmp_path / "clean")
    assert library.stat().st_mtime_ns > 1


def test_changed_compiler_flags_rebuild(tmp_path, monkeypatch):
    library = build_runtime(tmp_path).parent / LIBRARY_NAME
    os.utime(library, ns=(2**62, 2**62))  # newer than any source: up to date by time
    build_runtime(tmp_path)
    assert library.stat().st_mtime_ns == 2**62  # same flags: kept
    monkeypatch.setenv("BTF_XR_RUNTIME_CFLAGS", "-DBTF_TEST_FLAG=1")
    build_runtime(tmp_path)
    assert library.stat().st_mtime_ns < 2**62  # new flags: rebuilt


def test_a_missing_compiler_or_header_is_named_with_its_apt_package(tmp_path, monkeypatch):
    assert missing_tools() == []  # this machine has them (tools/check_system.sh)
    headers = missing_tools(include_dir=tmp_path)
    assert any("openxr_platform.h" in m and "libopenxr-dev" in m for m in headers)
    assert any("EGL/egl.h" in m and "libegl-dev" in m for m in headers)
    monkeypatch.delenv("CC", raising=False)
    monkeypatch.setenv("PATH", str(tmp_path))  # no cc on it
    with pytest.raises(RuntimeBuildError, match=r"cc \(apt install gcc\)"):
        build_runtime(tmp_path / "nocc")


# ---------------------------------------------------------------------------------------------
# instance, system, views
# ---------------------------------------------------------------------------------------------
def test_instance_system_and_views_follow_the_script(xr_runtime, app_factory):
    xr_runtime.script(eye_size=[64, 48], display_period_s=0.02)
    names = [e.extension_name.decode() for e in xr.enumerate_instance_extension_properties()]
    assert set(EXTENSIONS) <= set(names)
    app = app_factory()
    props = xr.get_instance_properties(app.instance)
    assert props.runtime_name.decode() == "BTF test runtime"
    system = app.get_system()
    sysprops = xr.get_system_properties(app.instance, system)
    assert sysprops.tracking_properties.position_tracking
    assert list(xr.enumerate_view_configurations(app.instance, system)) == [STEREO]
    views = xr.enumerate_view_configuration_views(app.instance, system, STEREO)
    assert len(views) == 2
    for v in views:
        assert (v.recommended_image_rect_width, v.recommended_image_rect_height) == (64, 48)
        assert (v.max_image_rect_width, v.max_image_rect_height) == (256, 192)
    modes = xr.enumerate_environment_blend_modes(app.instance, system, STEREO)
    assert list(modes) == [xr.EnvironmentBlendMode.OPAQUE]
    req = app.graphics_requirements()
    assert req.min_api_version_supported.number() == xr.Version(3, 3, 0).number()
    assert req.max_api_version_supported.number() == xr.Version(4, 6, 0).number()
    path = xr.string_to_path(app.instance, "/user/hand/left")
    assert xr.path_to_string(app.instance, path) == "/user/hand/left"


def test_an_openxr_1_1_app_is_refused_by_this_1_0_runtime(xr_runtime, app_factory):
    with pytest.raises(xr.ApiVersionUnsupportedError):
        app_factory(api_version=xr.Version(1, 1, 0))


# ---------------------------------------------------------------------------------------------
# the session and the frame loop
# ---------------------------------------------------------------------------------------------
def test_two_frames_reach_focused_and_read_back_as_cleared_with_the_scripted_poses(
    xr_runtime, app_factory
):
    s45 = float(np.sin(np.pi / 8))  # 45 degrees about y (half angle pi/8)
    heads = [
        [0.0, 1.6, 0.0, 0.0, 0.0, 0.0, 1.0],
        [0.1, 1.5, -0.2, 0.0, s45, 0.0, float(np.cos(np.pi / 8))],
    ]
    ipd = 0.07
    xr_runtime.script(head=heads, ipd=ipd)
    app = app_factory()
    space, chains = start_running(app, formats=(GL_SRGB8_ALPHA8, GL_RGBA16F))
    colours = [
        [((0.25, 0.5, 0.75, 1.0), (1.0, 0.0, 0.0, 1.0)), ((0.1, 0.2, 0.3, 1.0), (0, 1, 0, 1))],
        [((0.6, 0.4, 0.2, 1.0), (0.0, 0.0, 1.0, 1.0)), ((0.9, 0.8, 0.7, 1.0), (0, 0, 0, 1))],
    ]
    located = []
    states = []
    for f in range(2):
        state, views = submit_frame(app, space, chains, colours[f])
        assert state.should_render
        states.append(state)
        located.append([(v.pose, v.fov) for v in views])
    app.poll()
    assert app.states[:5] == [S.IDLE, S.READY, S.SYNCHRONIZED, S.VISIBLE, S.FOCUSED]
    period = states[1].predicted_display_time - states[0].predicted_display_time
    assert period == states[0].predicted_display_period == 50_000_000  # default 0.05 s

    frames = xr_runtime.captured()
    assert [f.frame for f in frames] == [0, 1]
    for f, frame in enumerate(frames):
        assert frame.display_time == states[f].predicted_display_time
        assert frame.space == "LOCAL"
        np.testing.assert_allclose(frame.head, heads[f], atol=1e-6)
        assert len(frame.views) == 2
        head_pos, head_q = np.array(heads[f][:3]), heads[f][3:]
        for i, view in enumerate(frame.views):
            assert view.image.shape == (72, 96, 4)
            assert view.rect == (0, 0, 96, 72)
            tol = SRGB8_TOL if view.format == GL_SRGB8_ALPHA8 else RGBA16F_TOL
            colour, corner = colours[f][i]
            # row 0 is the bottom: the bottom-left quarter holds the corner colour
            np.testing.assert_allclose(
                view.image[:36, :48], np.broadcast_to(corner, (36, 48, 4)), atol=tol
            )
            np.testing.assert_allclose(
                view.image[36:, :], np.broadcast_to(colour, (36, 96, 4)), atol=tol
            )
            np.testing.assert_allclose(
                view.image[:, 48:], np.broadcast_to(colour, (72, 48, 4)), atol=tol
            )
            # the pose/fov recorded are the submitted ones (= what xrLocateViews returned)
            pose, fov = located[f][i]
            sub = (
                *[getattr(pose.position, a) for a in "xyz"],
                *[getattr(pose.orientation, a) for a in "xyzw"],
            )
            np.testing.assert_allclose(view.pose, sub, atol=1e-6)
            np.testing.assert_allclose(
                view.fov, (fov.angle_left, fov.angle_right, fov.angle_up, fov.angle_down), atol=1e-6
            )
            # and they follow the head path: eye = head -/+ ipd/2 along the head's x axis
            expected = head_pos + quat_rotate(head_q, [(-ipd / 2, ipd / 2)[i], 0.0, 0.0])
            np.testing.assert_allclose(view.pose[:3], expected, atol=1e-5)  # float32 poses
            np.testing.assert_allclose(view.pose[3:], head_q, atol=1e-6)
            np.testing.assert_allclose(view.located_pose, view.pose, atol=1e-6)
            assert view.readback_ok
    # the default FOVs are asymmetric, the outer side wider
    left, right = frames[0].views[0].fov, frames[0].views[1].fov
    assert -left[0] > left[1] and right[1] > -right[0]
    assert frames[0].views[0].encoding == "srgb"  # Mesa returns sRGB texels undecoded
    assert frames[0].views[1].encoding == "linear"

    # clean shutdown: the spec's sequence down to EXITING
    xr.request_exit_session(app.session)
    app.poll()
    xr.end_session(app.session)
    app.poll()
    assert app.states[5:] == [S.VISIBLE, S.SYNCHRONIZED, S.STOPPING, S.IDLE, S.EXITING]


def test_a_sub_image_rect_is_read_back_alone(xr_runtime, app_factory):
    """Both eyes side by side in one swapchain, as apps that share an image do."""
    xr_runtime.script(eye_size=[32, 24])
    app = app_factory()
    app.start()
    app.poll()
    app.begin()
    space = app.space(xr.ReferenceSpaceType.STAGE)
    sc, images = app.swapchain(GL_RGBA8, 64, 24)
    chain = (sc, images, (64, 24))
    # one image for both views: clear it once per frame, so both views see the second clear
    state = xr.wait_frame(app.session, xr.FrameWaitInfo())
    xr.begin_frame(app.session, xr.FrameBeginInfo())
    _, views = xr.locate_views(
        app.session,
        xr.ViewLocateInfo(
            view_configuration_type=STEREO, display_time=state.predicted_display_time, space=space
        ),
    )
    index = xr.acquire_swapchain_image(sc, xr.SwapchainImageAcquireInfo())
    xr.wait_swapchain_image(sc, xr.SwapchainImageWaitInfo(timeout=xr.INFINITE_DURATION))
    app.clear_image(images[index], (64, 24), (0.2, 0.4, 0.6, 1.0), (1.0, 1.0, 1.0, 1.0))
    xr.release_swapchain_image(sc, xr.SwapchainImageReleaseInfo())
    proj = [
        xr.CompositionLayerProjectionView(
            pose=v.pose,
            fov=v.fov,
            sub_image=xr.SwapchainSubImage(
                swapchain=chain[0],
                image_rect=xr.Rect2Di(offset=xr.Offset2Di(32 * i, 0), extent=xr.Extent2Di(32, 24)),
            ),
        )
        for i, v in enumerate(views)
    ]
    layer = xr.CompositionLayerProjection(space=space, views=proj)
    xr.end_frame(
        app.session,
        xr.FrameEndInfo(display_time=state.predicted_display_time, layers=[ctypes.byref(layer)]),
    )
    frame = xr_runtime.captured()[0]
    assert frame.space == "STAGE"
    left, right = frame.views
    assert left.rect == (0, 0, 32, 24) and right.rect == (32, 0, 32, 24)
    assert (left.width, left.height) == (64, 24)
    # RGBA8: 0.5/255 quantisation; the white corner is the left view's bottom-left 32x12 only
    np.testing.assert_allclose(left.image[:12, :], 1.0, atol=0.5 / 255 + 1e-6)
    np.testing.assert_allclose(
        left.image[12:, :, :3], np.broadcast_to((0.2, 0.4, 0.6), (12, 32, 3)), atol=0.5 / 255 + 1e-6
    )
    np.testing.assert_allclose(
        right.image[..., :3], np.broadcast_to((0.2, 0.4, 0.6), (24, 32, 3)), atol=0.5 / 255 + 1e-6
    )


def test_the_app_context_need_not_be_current(xr_runtime, app_factory):
    """XR_KHR_opengl_enable lets the app leave its context unbound during the graphics calls:
    the runtime binds it itself and restores the thread's binding: none, or the context that
    was current before the app's (the app gives that back on release, as a guest should)."""
    app = app_factory()
    app.start()
    app.egl.release_current()
    before = app.egl.lib.eglGetCurrentContext()
    assert before != app.egl.context
    _, images = app.swapchain(GL_RGBA8, 16, 16)
    assert len(images) == 3 and all(images)
    assert app.egl.lib.eglGetCurrentContext() == before
    app.egl.make_current()


def test_should_render_can_wait_for_visible_as_monado_does(xr_runtime, app_factory):
    xr_runtime.script(should_render_from="visible")
    app = app_factory()
    start_running(app)
    first = xr.wait_frame(app.session, xr.FrameWaitInfo())
    xr.begin_frame(app.session, xr.FrameBeginInfo())
    xr.end_frame(app.session, xr.FrameEndInfo(display_time=first.predicted_display_time))
    second = xr.wait_frame(app.session, xr.FrameWaitInfo())
    assert not first.should_render and second.should_render
    assert xr_runtime.captured() == []  # no projection layer, no capture


# ---------------------------------------------------------------------------------------------
# faults
# ---------------------------------------------------------------------------------------------
def test_no_system(xr_runtime, app_factory):
    xr_runtime.script(system_available=False)
    app = app_factory()
    with pytest.raises(xr.FormFactorUnavailableError):
        app.get_system()


def test_an_extension_not_offered_is_refused(xr_runtime, app_factory, capfd):
    xr_runtime.script(extensions=["XR_KHR_opengl_enable"])
    names = [e.extension_name.decode() for e in xr.enumerate_instance_extension_properties()]
    assert "XR_KHR_opengl_enable" in names and "XR_MNDX_egl_enable" not in names
    with pytest.raises(xr.ExtensionNotPresentError):
        app_factory()
    # the real loader already refuses what the runtime does not enumerate (and says so)
    assert "XR_MNDX_egl_enable" in capfd.readouterr().err
    # without XR_MNDX_egl_enable an EGL session cannot be made
    app = app_factory(extensions=["XR_KHR_opengl_enable"])
    with pytest.raises(xr.GraphicsDeviceInvalidError):
        app.start()


@pytest.mark.parametrize(
    ("overrides", "message"),
    [
        ({"eye_size": [64]}, "eye_size must be [width, height]"),
        ({"eye_sise": [64, 48]}, 'unknown key "eye_sise"'),
        ({"head": [[0, 0, 0, 0, 0, 0, 0]]}, "head[0] has a zero quaternion"),
    ],
)
def test_a_bad_script_fails_instance_creation_saying_why(
    xr_runtime, app_factory, capfd, overrides, message
):
    xr_runtime.script(**overrides)
    with pytest.raises(xr.RuntimeFailureError):
        app_factory()
    assert message in capfd.readouterr().err


def test_another_view_count(xr_runtime, app_factory):
    xr_runtime.script(views=3)
    app = app_factory()
    space, chains = start_running(app, formats=(GL_RGBA8,) * 2)
    system_views = xr.enumerate_view_configuration_views(app.instance, app.system, STEREO)
    assert len(system_views) == 3
    state = xr.wait_frame(app.session, xr.FrameWaitInfo())
    _, views = xr.locate_views(
        app.session,
        xr.ViewLocateInfo(
            view_configuration_type=STEREO, display_time=state.predicted_display_time, space=space
        ),
    )
    assert len(views) == 3
    # an app that assumes two views submits a layer the runtime refuses
    with pytest.raises(xr.ValidationFailureError):
        xr.begin_frame(app.session, xr.FrameBeginInfo())
        proj = [
            xr.CompositionLayerProjectionView(
                pose=views[i].pose,
                fov=views[i].fov,
                sub_image=xr.SwapchainSubImage(
                    swapchain=chains[i][0], image_rect=xr.Rect2Di(extent=xr.Extent2Di(96, 72))
                ),
            )
            for i in range(2)
        ]
        for sc, _, _ in chains:
            xr.acquire_swapchain_image(sc, xr.SwapchainImageAcquireInfo())
            xr.wait_swapchain_image(sc, xr.SwapchainImageWaitInfo(timeout=xr.INFINITE_DURATION))
            xr.release_swapchain_image(sc, xr.SwapchainImageReleaseInfo())
        layer = xr.CompositionLayerProjection(space=space, views=proj)
        xr.end_frame(
            app.session,
            xr.FrameEndInfo(
                display_time=state.predicted_display_time, layers=[ctypes.byref(layer)]
            ),
        )


def test_swapchain_formats_and_an_unoffered_format(xr_runtime, app_factory):
    app = app_factory()
    app.start()
    assert list(xr.enumerate_swapchain_formats(app.session)) == [
        GL_SRGB8_ALPHA8,
        GL_RGBA8,
        GL_RGBA16F,
    ]
    with pytest.raises(xr.SwapchainFormatUnsupportedError):
        app.swapchain(GL_RGBA32F, 16, 16)


def test_a_runtime_offering_only_formats_the_app_cannot_use(xr_runtime, app_factory):
    xr_runtime.script(formats=[0x8059])  # GL_RGB10_A2
    app = app_factory()
    app.start()
    assert list(xr.enumerate_swapchain_formats(app.session)) == [0x8059]
    with pytest.raises(xr.SwapchainFormatUnsupportedError):
        app.swapchain(GL_SRGB8_ALPHA8, 16, 16)


def test_call_order_errors(xr_runtime, app_factory):
    app = app_factory()
    app.get_system()
    # the graphics requirements must be asked for before the session
    with pytest.raises(xr.GraphicsRequirementsCallMissingError):
        app.start(requirements=False)
    app.start()
    with pytest.raises(xr.SessionNotRunningError):
        xr.wait_frame(app.session, xr.FrameWaitInfo())
    app.poll()
    app.begin()
    with pytest.raises(xr.SessionRunningError):
        app.begin()
    space = app.space()
    sc, _ = app.swapchain(GL_RGBA8, 96, 72)
    with pytest.raises(xr.CallOrderInvalidError):  # begin without wait
        xr.begin_frame(app.session, xr.FrameBeginInfo())
    with pytest.raises(xr.CallOrderInvalidError):  # end without begin
        xr.end_frame(app.session, xr.FrameEndInfo(display_time=1))
    with pytest.raises(xr.CallOrderInvalidError):  # wait image without acquire
        xr.wait_swapchain_image(sc, xr.SwapchainImageWaitInfo(timeout=0))
    with pytest.raises(xr.CallOrderInvalidError):  # release without acquire
        xr.release_swapchain_image(sc, xr.SwapchainImageReleaseInfo())
    assert xr.acquire_swapchain_image(sc, xr.SwapchainImageAcquireInfo()) == 0
    with pytest.raises(xr.CallOrderInvalidError):  # release without wait
        xr.release_swapchain_image(sc, xr.SwapchainImageReleaseInfo())
    state = xr.wait_frame(app.session, xr.FrameWaitInfo())
    xr.begin_frame(app.session, xr.FrameBeginInfo())
    full = xr.Rect2Di(extent=xr.Extent2Di(96, 72))
    view = xr.CompositionLayerProjectionView(
        pose=xr.Posef(),
        fov=xr.Fovf(-0.5, 0.5, 0.5, -0.5),
        sub_image=xr.SwapchainSubImage(swapchain=sc, image_rect=full),
    )
    layer = xr.CompositionLayerProjection(space=space, views=[view, view])
    end = xr.FrameEndInfo(display_time=state.predicted_display_time, layers=[ctypes.byref(layer)])
    with pytest.raises(xr.LayerInvalidError):  # the swapchain has no released image yet
        xr.end_frame(app.session, end)
    xr.wait_swapchain_image(sc, xr.SwapchainImageWaitInfo(timeout=0))
    xr.release_swapchain_image(sc, xr.SwapchainImageReleaseInfo())
    view.sub_image.image_rect = xr.Rect2Di(offset=xr.Offset2Di(1, 0), extent=xr.Extent2Di(96, 72))
    layer = xr.CompositionLayerProjection(space=space, views=[view, view])
    with pytest.raises(xr.SwapchainRectInvalidError):
        xr.end_frame(
            app.session,
            xr.FrameEndInfo(
                display_time=state.predicted_display_time, layers=[ctypes.byref(layer)]
            ),
        )
    # a begun frame that was never ended is discarded by the next xrBeginFrame
    xr.wait_frame(app.session, xr.FrameWaitInfo())
    with pytest.raises(xr.FrameDiscarded):
        xr.begin_frame(app.session, xr.FrameBeginInfo())
    with pytest.raises(xr.SessionNotStoppingError):
        xr.end_session(app.session)


def test_session_loss_after_the_scripted_frame_count(xr_runtime, app_factory, capfd):
    xr_runtime.script(lose_session_after_frames=2)
    app = app_factory()
    space, chains = start_running(app, formats=(GL_RGBA8, GL_RGBA8))
    colours = [((0.5, 0.5, 0.5, 1.0), (0.0, 0.0, 0.0, 1.0))] * 2
    for _ in range(2):
        submit_frame(app, space, chains, colours)
    app.poll()
    assert app.states[-1] == S.LOSS_PENDING
    with pytest.raises(xr.SessionLostError):
        xr.wait_frame(app.session, xr.FrameWaitInfo())
    with pytest.raises(xr.SessionLostError):
        xr.acquire_swapchain_image(chains[0][0], xr.SwapchainImageAcquireInfo())
    assert "the session is lost after 2 frames" in capfd.readouterr().err
    assert len(xr_runtime.captured()) == 2
    # destroying a lost session (and its children) is allowed
    xr.destroy_session(app.session)
    app.session, app.swapchains, app.spaces = None, [], []


def test_readback_decodes_srgb_exactly_as_gl_samples_it():
    """The reader's decode is the IEC 61966-2-1 curve (0.5 encoded -> 0.214041 linear)."""
    np.testing.assert_allclose(
        srgb_to_linear(np.array([0.0, 0.04045, 0.5, 1.0])),
        [0.0, 0.04045 / 12.92, 0.214041, 1.0],
        atol=1e-6,
    )


def test_quad_layers_are_accepted_beside_the_projection_and_not_captured(xr_runtime, app_factory):
    app = app_factory()
    space, chains = start_running(app, size=(32, 24), formats=(GL_RGBA8, GL_RGBA8))
    hud, _ = app.swapchain(GL_RGBA8, 16, 8)
    colours = [((0.5, 0.5, 0.5, 1.0), (0.0, 0.0, 0.0, 1.0))] * 2
    submit_frame(app, space, chains, colours)  # releases an image of each eye swapchain
    quad = xr.CompositionLayerQuad(
        space=space,
        pose=xr.Posef(position=xr.Vector3f(0, 0, -1)),
        size=xr.Extent2Df(0.5, 0.25),
        sub_image=xr.SwapchainSubImage(
            swapchain=hud, image_rect=xr.Rect2Di(extent=xr.Extent2Di(16, 8))
        ),
    )
    state = xr.wait_frame(app.session, xr.FrameWaitInfo())
    xr.begin_frame(app.session, xr.FrameBeginInfo())
    end = xr.FrameEndInfo(display_time=state.predicted_display_time, layers=[ctypes.byref(quad)])
    with pytest.raises(xr.LayerInvalidError):  # the HUD swapchain was never released
        xr.end_frame(app.session, end)
    xr.acquire_swapchain_image(hud, xr.SwapchainImageAcquireInfo())
    xr.wait_swapchain_image(hud, xr.SwapchainImageWaitInfo(timeout=0))
    xr.release_swapchain_image(hud, xr.SwapchainImageReleaseInfo())
    xr.end_frame(app.session, end)
    assert len(xr_runtime.captured()) == 1  # only the frame with a projection layer


def test_pace_blocks_wait_frame_to_the_display_period(xr_runtime, app_factory):
    period = 0.03
    xr_runtime.script(pace=True, display_period_s=period)
    app = app_factory()
    start_running(app, formats=())
    start = time.monotonic()
    for _ in range(4):
        state = xr.wait_frame(app.session, xr.FrameWaitInfo())
        xr.begin_frame(app.session, xr.FrameBeginInfo())
        xr.end_frame(app.session, xr.FrameEndInfo(display_time=state.predicted_display_time))
    # frame k's slot opens at t0 + k * period: 4 frames span at least 3 periods (a lower bound
    # only: a loaded machine may take longer, never shorter)
    assert time.monotonic() - start >= 3 * period


def test_end_frame_reads_the_app_context_while_another_is_current(xr_runtime, app_factory):
    """The capture binds the session's context for its readback and gives the thread back the
    context that was current (here a second one), as XR_KHR_opengl_enable requires."""
    from xr_runtime.egl import create_egl_context

    app = app_factory()
    space, chains = start_running(app, size=(16, 8), formats=(GL_RGBA8, GL_RGBA8))
    colours = [((0.0, 0.5, 1.0, 1.0), (1.0, 0.5, 0.0, 1.0))] * 2
    state = xr.wait_frame(app.session, xr.FrameWaitInfo())
    xr.begin_frame(app.session, xr.FrameBeginInfo())
    proj = []
    for sc, images, size in chains:
        index = xr.acquire_swapchain_image(sc, xr.SwapchainImageAcquireInfo())
        xr.wait_swapchain_image(sc, xr.SwapchainImageWaitInfo(timeout=0))
        app.clear_image(images[index], size, *colours[0])
        xr.release_swapchain_image(sc, xr.SwapchainImageReleaseInfo())
        rect = xr.Rect2Di(extent=xr.Extent2Di(*size))
        proj.append(
            xr.CompositionLayerProjectionView(
                pose=xr.Posef(),
                fov=xr.Fovf(-0.5, 0.5, 0.5, -0.5),
                sub_image=xr.SwapchainSubImage(swapchain=sc, image_rect=rect),
            )
        )
    other = create_egl_context()  # now current instead of the app's
    try:
        layer = xr.CompositionLayerProjection(space=space, views=proj)
        xr.end_frame(
            app.session,
            xr.FrameEndInfo(
                display_time=state.predicted_display_time, layers=[ctypes.byref(layer)]
            ),
        )
        assert other.lib.eglGetCurrentContext() == other.context
    finally:
        other.destroy()
        app.egl.make_current()
    view = xr_runtime.captured()[0].views[0]
    # RGBA8 quantisation: half a step, 0.5/255
    np.testing.assert_allclose(view.image[-1, -1], colours[0][0], atol=0.5 / 255 + 1e-6)
    np.testing.assert_allclose(view.image[0, 0], colours[0][1], atol=0.5 / 255 + 1e-6)


def test_the_view_space_follows_the_head(xr_runtime, app_factory):
    head = [0.3, 1.7, -0.5, 0.0, 0.0, float(np.sin(0.2)), float(np.cos(0.2))]
    xr_runtime.script(head=[head])
    app = app_factory()
    local, _ = start_running(app, formats=())
    view = app.space(xr.ReferenceSpaceType.VIEW)
    state = xr.wait_frame(app.session, xr.FrameWaitInfo())
    loc = xr.locate_space(view, local, state.predicted_display_time)
    assert loc.location_flags & xr.SpaceLocationFlags.POSITION_TRACKED_BIT
    got = [*(getattr(loc.pose.position, a) for a in "xyz")]
    got += [getattr(loc.pose.orientation, a) for a in "xyzw"]
    np.testing.assert_allclose(got, head, atol=1e-6)  # float32 poses
    # eyes located in VIEW space sit at -/+ ipd/2 on x, unrotated
    _, views = xr.locate_views(
        app.session,
        xr.ViewLocateInfo(
            view_configuration_type=STEREO, display_time=state.predicted_display_time, space=view
        ),
    )
    for i, v in enumerate(views):
        np.testing.assert_allclose(
            [v.pose.position.x, v.pose.position.y, v.pose.position.z],
            [(-0.0315, 0.0315)[i], 0.0, 0.0],
            atol=1e-6,
        )


def test_wait_frame_may_run_on_another_thread(xr_runtime, app_factory):
    """The pipelined pattern the spec allows: xrWaitFrame on one thread, begin/end on another."""
    import threading

    xr_runtime.script(pace=True, display_period_s=0.01)
    app = app_factory()
    start_running(app, formats=())
    times = []
    for _ in range(3):
        states = []
        waiter = threading.Thread(
            target=lambda out=states: out.append(xr.wait_frame(app.session, xr.FrameWaitInfo()))
        )
        waiter.start()
        app.poll()  # concurrently with the (pacing) wait
        waiter.join(timeout=10)
        xr.begin_frame(app.session, xr.FrameBeginInfo())
        xr.end_frame(app.session, xr.FrameEndInfo(display_time=states[0].predicted_display_time))
        times.append(states[0].predicted_display_time)
    assert np.diff(times).tolist() == [10_000_000, 10_000_000]


def test_actions_exist_but_no_controller_is_ever_active(xr_runtime, app_factory):
    app = app_factory()
    space, chains = start_running(app, size=(16, 8), formats=(GL_RGBA8, GL_RGBA8))
    action_set = xr.create_action_set(
        app.instance,
        xr.ActionSetCreateInfo(action_set_name="btf", localized_action_set_name="BTF", priority=0),
    )
    select = xr.create_action(
        action_set,
        xr.ActionCreateInfo(
            action_type=xr.ActionType.BOOLEAN_INPUT,
            action_name="select",
            localized_action_name="Select",
        ),
    )
    profile = xr.string_to_path(app.instance, "/interaction_profiles/khr/simple_controller")
    binding = xr.string_to_path(app.instance, "/user/hand/right/input/select/click")
    xr.suggest_interaction_profile_bindings(
        app.instance,
        xr.InteractionProfileSuggestedBinding(
            interaction_profile=profile,
            suggested_bindings=[xr.ActionSuggestedBinding(select, binding)],
        ),
    )
    xr.attach_session_action_sets(
        app.session, xr.SessionActionSetsAttachInfo(action_sets=[action_set])
    )
    sync = xr.ActionsSyncInfo(active_action_sets=[xr.ActiveActionSet(action_set, 0)])
    with pytest.raises(xr.SessionNotFocused):  # a qualified success before FOCUSED
        xr.sync_actions(app.session, sync)
    submit_frame(app, space, chains, [((0, 0, 0, 1), (0, 0, 0, 1))] * 2)  # -> FOCUSED
    xr.sync_actions(app.session, sync)
    state = xr.get_action_state_boolean(app.session, xr.ActionStateGetInfo(action=select))
    assert not state.is_active and not state.current_state
    xr.destroy_action_set(action_set)  # its actions go with it
    with pytest.raises(xr.HandleInvalidError):
        xr.get_action_state_boolean(app.session, xr.ActionStateGetInfo(action=select))


def test_an_unreadable_format_is_captured_as_zeros_and_said_so(xr_runtime, app_factory, capfd):
    xr_runtime.script(formats=[GL_RGBA8UI])
    app = app_factory()
    app.start()
    app.poll()
    app.begin()
    space = app.space()
    sc, _ = app.swapchain(GL_RGBA8UI, 8, 8)
    xr.acquire_swapchain_image(sc, xr.SwapchainImageAcquireInfo())
    xr.wait_swapchain_image(sc, xr.SwapchainImageWaitInfo(timeout=0))
    xr.release_swapchain_image(sc, xr.SwapchainImageReleaseInfo())
    state = xr.wait_frame(app.session, xr.FrameWaitInfo())
    xr.begin_frame(app.session, xr.FrameBeginInfo())
    rect = xr.Rect2Di(extent=xr.Extent2Di(8, 8))
    view = xr.CompositionLayerProjectionView(
        pose=xr.Posef(),
        fov=xr.Fovf(-0.5, 0.5, 0.5, -0.5),
        sub_image=xr.SwapchainSubImage(swapchain=sc, image_rect=rect),
    )
    layer = xr.CompositionLayerProjection(space=space, views=[view, view])
    xr.end_frame(
        app.session,
        xr.FrameEndInfo(display_time=state.predicted_display_time, layers=[ctypes.byref(layer)]),
    )
    views = xr_runtime.captured()[0].views
    assert not views[0].readback_ok and not views[0].image.any()
    assert "captured as zeros" in capfd.readouterr().err


# ---------------------------------------------------------------------------------------------
# what Monado does (issue 30 item 8): a head never still, paced frames, a teardown that crashes
def _head_at(app, space, state):
    _, views = xr.locate_views(
        app.session,
        xr.ViewLocateInfo(
            view_configuration_type=STEREO, display_time=state.predicted_display_time, space=space
        ),
    )
    p, q = views[0].pose.position, views[0].pose.orientation
    return np.array([p.x, p.y, p.z, q.x, q.y, q.z, q.w])


def test_head_motion_moves_the_head_slightly_every_frame(xr_runtime, app_factory):
    """``head_motion`` [metres, radians]: every frame's pose differs from the last, by no
    more than the amplitudes (a sway about the scripted pose, the same for the same frame)."""
    xr_runtime.script(head_motion=[0.002, 0.004])
    app = app_factory()
    space, _ = start_running(app, formats=())
    poses = []
    for _ in range(6):
        state = xr.wait_frame(app.session, xr.FrameWaitInfo())
        xr.begin_frame(app.session, xr.FrameBeginInfo())
        poses.append(_head_at(app, space, state))
        xr.end_frame(app.session, xr.FrameEndInfo(display_time=state.predicted_display_time))
    poses = np.array(poses)
    steps = np.abs(np.diff(poses, axis=0))
    assert (steps.max(axis=1) > 1e-5).all(), "a frame kept the last frame's pose"
    left_eye_still = np.array([-0.0315, 0, 0])  # the default head at the origin, unrotated
    assert np.abs(poses[:, :3] - left_eye_still).max() <= 0.002 * 1.5 + 1e-6
    assert np.abs(poses[:, 3:6]).max() <= np.sin(0.004 / 2) + 1e-6  # half the turn's angle


def test_pace_hz_from_the_environment(xr_runtime, app_factory, monkeypatch):
    """BTF_XR_TEST_PACE_HZ paces frames at that rate over the script's period and pace."""
    monkeypatch.setenv("BTF_XR_TEST_PACE_HZ", "40")
    xr_runtime.script(pace=False, display_period_s=0.001)
    app = app_factory()
    start_running(app, formats=())
    start = time.monotonic()
    for _ in range(4):
        state = xr.wait_frame(app.session, xr.FrameWaitInfo())
        assert state.predicted_display_period == 25_000_000
        xr.begin_frame(app.session, xr.FrameBeginInfo())
        xr.end_frame(app.session, xr.FrameEndInfo(display_time=state.predicted_display_time))
    assert time.monotonic() - start >= 3 * 0.025


STRICT_APP = """
import sys, ctypes, xr
from xr_runtime.client import GL_RGBA8, App, start_running
app = App()
space, chains = start_running(app, size=(16, 8), formats=(GL_RGBA8, GL_RGBA8))
app.poll()
state = xr.wait_frame(app.session, xr.FrameWaitInfo())
xr.begin_frame(app.session, xr.FrameBeginInfo())
case = sys.argv[1]
if case == "acquired":
    xr.acquire_swapchain_image(chains[0][0], xr.SwapchainImageAcquireInfo())
    xr.destroy_swapchain(chains[0][0])
if case in ("clean", "running"):
    xr.end_frame(app.session, xr.FrameEndInfo(display_time=state.predicted_display_time))
if case == "clean":
    xr.request_exit_session(app.session)
    app.poll()
    xr.end_session(app.session)
app.gl.finish()
app.swapchains = []  # destroyed with the session (its children)
xr.destroy_session(app.session)
print("destroyed", flush=True)
"""


@pytest.mark.parametrize(
    ("case", "words"),
    [
        ("begun", "xrDestroySession destroys a session with a frame begun and not ended"),
        ("acquired", "with an image acquired and not released"),
        ("running", "destroys a running session"),
        ("clean", None),
    ],
)
def test_strict_teardown_aborts_where_monado_crashed(xr_runtime, tmp_path, case, words):
    """``strict_teardown``: a teardown in the order the spec allows passes; one that leaves a
    frame begun, an image acquired or the session running aborts the process (Monado
    crashed there: issue 30 item 1), saying why."""
    import subprocess
    import sys

    xr_runtime.script(strict_teardown=True)
    tests_dir = os.path.dirname(os.path.dirname(os.path.abspath(__file__)))
    env = {**os.environ, "PYTHONPATH": tests_dir}
    proc = subprocess.run(
        [sys.executable, "-c", STRICT_APP, case],
        capture_output=True, text=True, env=env, timeout=60, check=False,
    )  # fmt: skip
    if words is None:
        assert proc.returncode == 0, proc.stderr
        assert "destroyed" in proc.stdout and "strict teardown" not in proc.stderr
    else:
        assert proc.returncode == -6, (proc.returncode, proc.stderr)  # SIGABRT
        assert words in proc.stderr
