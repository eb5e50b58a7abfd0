"""The bridge's errors: each says what is missing or what to do, and carries the CLI's exit
code (``python -m btf_addon bridge``; the Blender operator shows the message)."""

from __future__ import annotations

from ..core.errors import BTFMaterialsError


class BridgeError(BTFMaterialsError):
    """A failure of the XTAL bridge. ``exit_code``: the CLI's exit status for it."""

    exit_code: int = 1


class NoRuntimeError(BridgeError):
    """No OpenXR runtime: the loader found none, or ``XR_RUNTIME_JSON`` names a bad file."""

    exit_code = 3


class NoHeadsetError(BridgeError):
    """A runtime, but no head-mounted display (form factor unavailable or unsupported)."""

    exit_code = 4


class SessionLostError(BridgeError):
    """The runtime lost the session (or the instance) while the bridge ran."""

    exit_code = 5


class UnsupportedRuntimeError(BridgeError):
    """The runtime lacks what the bridge needs: two stereo views, a swapchain format it can
    write, an OpenGL graphics binding for the context it has."""

    exit_code = 6
