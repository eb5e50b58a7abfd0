"""``python -m btf_addon …``: the command-line tools (doctor, info, eval, swatch, synth, ...)."""

import signal
import sys

from .cli.main import main

code = main()
# The command is over and its exit status decided: a Ctrl-C now (Blender's teardown can take a
# second) would end the process by SIGINT (-2) and hide that status.
signal.signal(signal.SIGINT, signal.SIG_IGN)
signal.signal(signal.SIGTERM, signal.SIG_IGN)
if "bpy" in sys.modules:  # Blender as a module (render): its teardown differs per version
    from .blender.compat import exit_python

    exit_python(code)
sys.exit(code)
