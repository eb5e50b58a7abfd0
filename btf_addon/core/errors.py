"""The add-on's exceptions: one root, so callers catch one type and the CLI has one boundary.

Every error the add-on raises on purpose derives from ``BTFMaterialsError`` and carries the
exit status the command line ends with (cli/main.py): 2 for input or a device the user can fix
(``BTFError``, ``DeviceError``), 1 for a bug (a kernel or shader that does not compile), the
bridge's own codes 3–6 (xr/errors.py). Device errors also derive from RuntimeError, as the
driver failures they report always have. Each message names the file, device or problem.
"""

from __future__ import annotations


class BTFMaterialsError(Exception):
    """Root of the add-on's errors. ``exit_code``: the command line's exit status for it."""

    exit_code: int = 1


class BTFError(BTFMaterialsError):
    """Input (a BTF, an environment, a size, a file) that cannot be used as given."""

    exit_code = 2


class DeviceError(BTFMaterialsError, RuntimeError):
    """A device or driver the work needs is missing or refuses (OpenCL, EGL/OpenGL): the
    message says what to install."""

    exit_code = 2


class BuildError(BTFMaterialsError, RuntimeError):
    """Device code (an OpenCL kernel, a GLSL shader) that does not compile: a bug in kernels/
    or shaders/, or a driver that rejects valid code; the message quotes the compiler."""


class BTFFormatError(BTFError):
    """A file is missing, truncated, corrupt or inconsistent with the rest of the material."""


class UnsupportedBTFError(BTFError):
    """A valid file that uses a feature this add-on does not implement."""
