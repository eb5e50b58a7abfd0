"""The command-line tools from Blender's own command line: ``blender --command btf …``.

Someone who installed only the extension zip has Blender, not a Python with this package on
its path, so ``python -m btf_addon …`` is out of reach. Blender 4.2+ lets an extension register
command-line commands (``bpy.utils.register_cli_command``); Blender calls the function with the
arguments after the command's name and exits with what it returns. It is the same parser, the
same error boundary and the same exit codes as ``python -m btf_addon`` (cli/main.py): only the
program name in usage lines differs. Registered while the add-on is enabled (btf_addon's
``register``), unregistered when it is disabled.
"""

from __future__ import annotations

#: ``blender --command btf render --blend f.blend -o out.png``
COMMAND = "btf"
PROG = f"blender --command {COMMAND}"

_handle = None


def execute(argv: list[str]) -> int:
    """What ``blender --command btf ARGS`` runs: ``python -m btf_addon ARGS``'s exit code."""
    from .main import main

    try:
        return main(list(argv), prog=PROG)
    except SystemExit as exc:  # argparse's usage errors (2) and --help (0): a code, as in Python
        return exc.code if isinstance(exc.code, int) else (0 if exc.code is None else 2)


def register() -> None:
    global _handle
    import bpy

    register_cli = getattr(bpy.utils, "register_cli_command", None)
    if register_cli is None or _handle is not None:  # before 4.2: no extension commands
        return
    _handle = register_cli(COMMAND, execute)


def unregister() -> None:
    global _handle
    import bpy

    if _handle is not None:
        bpy.utils.unregister_cli_command(_handle)
        _handle = None
