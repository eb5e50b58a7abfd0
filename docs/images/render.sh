#!/usr/bin/env bash
# The user guide's pictures, rendered by the project itself from its synthetic demo scene (no
# research data): `docs/images/render.sh` from the repository root. Prints each render's time.
set -euo pipefail
PY=${PY:-.venv/bin/python}
out=docs/images
render() {
  local name=$1; shift
  local t0=$SECONDS
  "$PY" -m btf_addon render --demo --resolution 480x270 -o "$out/$name.png" "$@" >/dev/null
  echo "$name: $((SECONDS - t0)) s ($*)"
}
render demo-virtual-16 --final-mode virtual --lights 16
render demo-virtual-256 --final-mode virtual --lights 256
render demo-sampled-64 --final-mode sampled --samples 64 --bounces 4
"$PY" tools/render_guide_pictures.py --output "$out"  # stereo F12, asset library previews
rm -rf "$out/demo_data"  # the demo's generated BTFs, written beside the output
