"""``python -m btf_addon …``: the command-line tools (doctor, info, eval, swatch, synth, ...)."""

import sys

from .cli.main import main

sys.exit(main())
