"""``python -m btf_addon …``: the command-line tools (doctor, info, eval, swatch, synth, ...)."""

import sys

from .cli.main import main

code = main()
if "bpy" in sys.modules:  # Blender as a module (render): its teardown differs per version
    from .blender.compat import exit_python

    exit_python(code)
sys.exit(code)
