"""``envmap``: virtual lights from an equirectangular EXR."""

from __future__ import annotations

from pathlib import Path

import numpy as np

from ..core import memory
from ..core.errors import BTFError
from ..core.fileio import atomic_write, check_output
from ..core.formats.imageio import exr_size, read_exr
from ..core.sampling.envmap import Environment


def add_parser(sub) -> None:
    p = sub.add_parser("envmap", help="importance-sampled virtual lights from an HDR map (.npz)")
    p.add_argument("map", type=Path, help="equirectangular .exr (Blender's orientation)")
    p.add_argument("--lights", type=int, default=256, help="number of virtual lights N")
    p.add_argument("--seed", type=int, default=0, help="seed of the Sobol digital shift")
    p.add_argument(
        "--rotation",
        type=float,
        default=0.0,
        help="Z rotation in degrees, as a Mapping node's Z rotation in the World",
    )
    p.add_argument("--strength", type=float, default=1.0, help="Background strength")
    p.add_argument("-o", "--output", required=True, type=Path)
    p.set_defaults(func=cmd_envmap)


def cmd_envmap(args) -> int:
    if args.lights < 1:
        raise BTFError(f"--lights must be at least 1, got {args.lights}")
    for flag, value in (("--rotation", args.rotation), ("--strength", args.strength)):
        if not np.isfinite(value):
            raise BTFError(f"{flag} must be a finite number, got {value}")
    if args.strength < 0:
        raise BTFError(f"--strength must be ≥ 0, got {args.strength}")
    out = args.output if args.output.suffix == ".npz" else args.output.with_suffix(".npz")
    check_output(out)
    width, height = exr_size(args.map)  # the header only: refuse a map too large before reading
    memory.require(
        memory.environment(width, height, f"the environment {args.map} of {width}×{height} pixels")
        + memory.virtual_lights(args.lights, f"{args.lights} virtual lights")
    )
    try:
        env = Environment(
            read_exr(args.map), strength=args.strength, rotation_z_rad=np.radians(args.rotation)
        )
    except ValueError as exc:
        raise BTFError(f"{args.map}: {exc}") from None
    lights = env.virtual_lights(args.lights, seed=args.seed)
    atomic_write(
        out,
        lambda fh: np.savez(
            fh,
            direction=lights.direction.astype(np.float32),
            radiance=lights.radiance.astype(np.float32),
            pdf=lights.pdf.astype(np.float32),
            nonfinite_pixels=np.int64(env.nonfinite_count),
        ),
    )
    if env.nonfinite_count:
        print(f"warning: {env.nonfinite_count} NaN/Inf pixels in {args.map} were set to 0")
    return 0
