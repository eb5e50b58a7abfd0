"""One description of a shader's interface → Blender's GPUShaderCreateInfo or GLSL 330 source.

Bodies live in shaders/*.glsl without declarations (Blender's create-info rule); the interface
here declares every resource once. For Blender, the description becomes create-info calls; for
moderngl it becomes ``#version 330`` declarations prepended to the same bodies.

Every shader is built with the packed table layout's defines (core/codecs/packed.py ``defines()``:
TABLE_WIDTH, header slots H_*/F_*, codec ids CODEC_*) beside its own: as create-info
``define`` calls for Blender and as ``#define`` lines after ``#version 330 core`` for moderngl.
shaders/btf_tables_lib.glsl writes none of those numbers itself.
"""

from __future__ import annotations

from dataclasses import dataclass, field
from pathlib import Path

from ..core.codecs import packed
from ..core.errors import BuildError
from ..core.sampling.world_pyramid import lobe_defines
from ..scene.bake_points import BIN_MARGIN

SHADERS_DIR = Path(__file__).resolve().parents[2] / "shaders"
MAX_SAMPLERS = 16  # Metal's limit: what every back end of this add-on keeps to
MAX_PUSH_CONSTANT_BYTES = 128

_GLSL_TYPES = {
    "FLOAT": "float",
    "VEC2": "vec2",
    "VEC3": "vec3",
    "VEC4": "vec4",
    "MAT4": "mat4",
    "INT": "int",
    "IVEC2": "ivec2",
    "IVEC4": "ivec4",
}
_TYPE_BYTES = {
    "FLOAT": 4,
    "VEC2": 8,
    "VEC3": 12,
    "VEC4": 16,
    "MAT4": 64,
    "INT": 4,
    "IVEC2": 8,
    "IVEC4": 16,
}
_SAMPLERS = {"FLOAT_2D": "sampler2D", "INT_2D": "isampler2D"}


class ShaderCompileError(BuildError):
    """A shader failed to compile or link; the message holds the shader name and the log."""


@dataclass(frozen=True)
class ShaderInterface:
    name: str
    vertex_inputs: tuple[tuple[int, str, str], ...]  # (location, type, name)
    fragment_outputs: tuple[tuple[int, str, str], ...]  # (slot, type, name)
    samplers: tuple[tuple[int, str, str], ...]  # (slot, FLOAT_2D | INT_2D, name)
    push_constants: tuple[tuple[str, str], ...] = ()  # (type, name)
    varyings: tuple[tuple[str, str], ...] = ()  # (type, name), smooth
    flat_varyings: tuple[tuple[str, str], ...] = ()  # (type, name): the provoking vertex's
    libraries: tuple[str, ...] = ()  # shaders/*.glsl prepended to the fragment body
    vertex_file: str = ""
    fragment_file: str = ""
    defines: dict[str, str] = field(default_factory=dict)

    def __post_init__(self) -> None:
        if len(self.samplers) > MAX_SAMPLERS:
            raise ValueError(f"{self.name}: {len(self.samplers)} samplers > {MAX_SAMPLERS}")
        size = sum(_TYPE_BYTES[t] for t, _ in self.push_constants)
        if size > MAX_PUSH_CONSTANT_BYTES:
            raise ValueError(f"{self.name}: {size} bytes of push constants > 128")

    def build_defines(self) -> dict[str, str]:
        """The packed layout's defines, then this shader's own (which may not redefine a
        layout name: the layout has one definition), as GLSL macro text."""
        layout = packed.defines()
        clash = sorted(set(layout) & set(self.defines))
        if clash:
            raise ValueError(f"{self.name}: defines {clash} would override the packed layout")
        return {k: str(v) for k, v in {**layout, **self.defines}.items()}

    def vertex_body(self) -> str:
        return (SHADERS_DIR / self.vertex_file).read_text()

    def fragment_body(self) -> str:
        parts = [(SHADERS_DIR / lib).read_text() for lib in self.libraries]
        return "\n".join([*parts, (SHADERS_DIR / self.fragment_file).read_text()])

    # --- moderngl / plain OpenGL ------------------------------------------------------------
    def glsl_330(self) -> tuple[str, str]:
        head = "#version 330 core\n" + "".join(
            f"#define {k} {v}\n" for k, v in self.build_defines().items()
        )
        uniforms = "".join(f"uniform {_GLSL_TYPES[t]} {n};\n" for t, n in self.push_constants)
        uniforms += "".join(f"uniform {_SAMPLERS[t]} {n};\n" for _, t, n in self.samplers)
        vs = head + uniforms
        vs += "".join(
            f"layout(location = {loc}) in {_GLSL_TYPES[t]} {n};\n"
            for loc, t, n in self.vertex_inputs
        )
        vs += "".join(f"out {_GLSL_TYPES[t]} {n};\n" for t, n in self.varyings)
        vs += "".join(f"flat out {_GLSL_TYPES[t]} {n};\n" for t, n in self.flat_varyings)
        fs = head + uniforms
        fs += "".join(f"in {_GLSL_TYPES[t]} {n};\n" for t, n in self.varyings)
        fs += "".join(f"flat in {_GLSL_TYPES[t]} {n};\n" for t, n in self.flat_varyings)
        fs += "".join(
            f"layout(location = {slot}) out {_GLSL_TYPES[t]} {n};\n"
            for slot, t, n in self.fragment_outputs
        )
        return vs + self.vertex_body(), fs + self.fragment_body()

    # --- Blender's gpu module -----------------------------------------------------------------
    def blender_create_info(self):
        import gpu

        info = gpu.types.GPUShaderCreateInfo()
        for loc, t, n in self.vertex_inputs:
            info.vertex_in(loc, t, n)
        for slot, t, n in self.fragment_outputs:
            info.fragment_out(slot, t, n)
        for slot, t, n in self.samplers:
            info.sampler(slot, t, n)
        for t, n in self.push_constants:
            info.push_constant(t, n)
        if self.varyings or self.flat_varyings:
            stage = gpu.types.GPUStageInterfaceInfo(f"{self.name}_iface")
            for t, n in self.varyings:
                stage.smooth(t, n)
            for t, n in self.flat_varyings:
                stage.flat(t, n)
            info.vertex_out(stage)
        for k, v in self.build_defines().items():
            info.define(k, v)
        info.vertex_source(self.vertex_body())
        info.fragment_source(self.fragment_body())
        return info


BTF_LIBRARIES = (
    "btf_tables_lib.glsl",
    "btf_colour_lib.glsl",
    "btf_mlvq_lib.glsl",
    "btf_dense_lib.glsl",
    "btf_svd_lib.glsl",
    "btf_eval_lib.glsl",
)

QUERY_SHADER = ShaderInterface(
    name="btf_query",
    vertex_inputs=((0, "VEC2", "pos"),),
    fragment_outputs=((0, "VEC4", "frag_color"),),
    samplers=(
        (0, "FLOAT_2D", "btf_int_tables"),
        (1, "FLOAT_2D", "btf_float_tables"),
        (2, "FLOAT_2D", "query_a"),
        (3, "FLOAT_2D", "query_b"),
    ),
    libraries=BTF_LIBRARIES,
    vertex_file="query_vert.glsl",
    fragment_file="query_frag.glsl",
)

SURFACE_SHADER = ShaderInterface(
    name="btf_surface",
    # blk: the vertex's mesh's row of the material blocks (one batch holds a material's meshes).
    # bake_tri, bake_bary: its triangle in the light bake (−1: none) and the corner's
    # barycentrics (0, 0), (1, 0), (0, 1), interpolated to the fragment's (shaders/bake_lib.glsl).
    vertex_inputs=(
        (0, "VEC3", "pos"),
        (1, "VEC3", "nor"),
        (2, "VEC2", "uv"),
        (3, "VEC4", "tan"),
        (4, "FLOAT", "blk"),
        (5, "FLOAT", "bake_tri"),
        (6, "VEC2", "bake_bary"),
    ),
    fragment_outputs=((0, "VEC4", "frag_color"),),
    samplers=(
        (0, "FLOAT_2D", "btf_int_tables"),
        (1, "FLOAT_2D", "btf_float_tables"),
        (2, "FLOAT_2D", "lights"),
        (3, "FLOAT_2D", "scene_lights"),
        (4, "FLOAT_2D", "material_blocks"),
        (5, "FLOAT_2D", "bake_index"),
        (6, "FLOAT_2D", "bake_values"),
        (7, "FLOAT_2D", "world_pyramid"),
    ),
    # world: the World's rotation and pyramid for an analytic object's baked light
    # (shaders/lobe_lib.glsl)
    push_constants=(
        ("MAT4", "clip_from_world"),
        ("VEC4", "camera"),
        ("VEC4", "light_range"),
        ("VEC4", "world"),
    ),
    # v_block: equal at a triangle's three corners, so interpolation keeps it (read rounded).
    varyings=(
        ("VEC3", "v_world"),
        ("VEC3", "v_normal"),
        ("VEC2", "v_uv"),
        ("VEC4", "v_tangent"),
        ("FLOAT", "v_block"),
        ("VEC2", "v_bake_bary"),
    ),
    # flat: the provoking vertex's value as it is; interpolating a constant rounds it by a
    # few ulps, which for a triangle number in the millions is a whole triangle
    flat_varyings=(("FLOAT", "v_bake_tri"),),
    libraries=(
        *BTF_LIBRARIES,
        "btf_mapping_lib.glsl",
        "scene_lights_lib.glsl",
        "bake_lib.glsl",
        "lobe_lib.glsl",
    ),
    vertex_file="surface_vert.glsl",
    fragment_file="surface_frag.glsl",
    defines={"BAKE_BIN_MARGIN": repr(float(BIN_MARGIN)), **lobe_defines()},
)

# The light bake's lookup alone, per query texel (gl/query.py ``glsl_bake_lookup``): what tests
# compare with the numpy rule (scene/bake_points.py ``playback``).
BAKE_QUERY_SHADER = ShaderInterface(
    name="btf_bake_query",
    vertex_inputs=((0, "VEC2", "pos"),),
    fragment_outputs=((0, "VEC4", "frag_color"),),
    samplers=(
        (0, "FLOAT_2D", "bake_index"),
        (1, "FLOAT_2D", "bake_values"),
        (2, "FLOAT_2D", "query_a"),
        (3, "FLOAT_2D", "query_b"),
    ),
    libraries=("bake_lib.glsl",),
    vertex_file="query_vert.glsl",
    fragment_file="bake_query_frag.glsl",
    defines=SURFACE_SHADER.defines,
)

BACKGROUND_SHADER = ShaderInterface(
    name="btf_background",
    vertex_inputs=((0, "VEC2", "pos"),),
    fragment_outputs=((0, "VEC4", "frag_color"),),
    samplers=((0, "FLOAT_2D", "environment"),),
    push_constants=(("MAT4", "world_from_clip"), ("VEC2", "viewport_size"), ("VEC2", "env_params")),
    libraries=("env_lib.glsl",),
    vertex_file="query_vert.glsl",
    fragment_file="background_frag.glsl",
)

RESOLVE_SHADER = ShaderInterface(
    name="btf_resolve",
    vertex_inputs=((0, "VEC2", "pos"),),
    fragment_outputs=((0, "VEC4", "frag_color"),),
    samplers=((0, "FLOAT_2D", "accumulation"), (1, "FLOAT_2D", "background")),
    push_constants=(("VEC4", "resolve_params"),),
    vertex_file="query_vert.glsl",
    fragment_file="resolve_frag.glsl",
)

# The VR HUD (gl/hud.py): a textured quad whose 4 view-space corners arrive as the columns of
# view_corners, placed by the static uv of each of its 6 vertices (no per-frame vertex upload).
HUD_SHADER = ShaderInterface(
    name="btf_hud",
    vertex_inputs=((0, "VEC2", "corner_uv"),),
    fragment_outputs=((0, "VEC4", "frag_color"),),
    samplers=((0, "FLOAT_2D", "hud_image"),),
    push_constants=(("MAT4", "clip_from_view"), ("MAT4", "view_corners")),
    varyings=(("VEC2", "v_uv"),),
    vertex_file="hud_vert.glsl",
    fragment_file="hud_frag.glsl",
)
