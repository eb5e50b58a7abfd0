"""Importance sampling of measured BTFs (core/sampling/btf_importance.py,
kernels/include/btf_sampling.h):
the OpenCL sampler against its own pdf (Pearson χ²), the pdf's normalisation and support, and
the Sampled render's mean unchanged by it."""

from __future__ import annotations

import math

import numpy as np
import pytest
from helpers import shared_material
from scipy.stats import chi2

from btf_addon.core.codecs.analytic import GGXBTF, LambertianBTF
from btf_addon.core.codecs.mlvq import MLVQBTF
from btf_addon.core.codecs.packed import INT_SLOT, pack
from btf_addon.core.sampling import btf_importance
from btf_addon.core.sampling.envmap import Environment, VirtualLights
from btf_addon.scene.primitives import uv_sphere
from btf_addon.scene.scene import Camera, Material, Scene, look_at

pytestmark = pytest.mark.opencl


def direction(theta_deg: float, phi_deg: float) -> np.ndarray:
    t, p = math.radians(theta_deg), math.radians(phi_deg)
    return np.array([math.sin(t) * math.cos(p), math.sin(t) * math.sin(p), math.cos(t)])


class Sampler:
    """kernels/btf_sampling.cl over one material's packed streams."""

    def __init__(self, cl_context, btf, defines=None):
        import pyopencl as cl

        from btf_addon.cl.programs import build_program

        self.cl, self.ctx, self.btf = cl, cl_context, btf
        self.packed = pack(btf, importance=True)
        program = build_program(
            cl_context.context, cl_context.device, "btf_sampling.cl", defines or {}
        )
        self.sample_kernel = cl.Kernel(program, "sample_directions")
        self.pdf_kernel = cl.Kernel(program, "direction_pdf")
        self.I, self.F = self._in(self.packed.ints), self._in(self.packed.floats)

    def _in(self, a):
        mf = self.cl.mem_flags
        data = np.ascontiguousarray(a, np.float32).ravel()
        return self.cl.Buffer(self.ctx.context, mf.READ_ONLY | mf.COPY_HOST_PTR, hostbuf=data)

    def _out(self, shape):
        host = np.empty(shape, np.float32)
        return host, self.cl.Buffer(self.ctx.context, self.cl.mem_flags.WRITE_ONLY, host.nbytes)

    def sample(self, wo, u, choice):
        """(N, 3) directions, the pdf the sampler states and bsdf_pdf's of them, from (N, 2)
        points and (N,) lobe choices."""
        n = len(u)
        wi, wi_buf = self._out((n, 3))
        pdf, pdf_buf = self._out(n)
        again, again_buf = self._out(n)
        wo4 = np.array([*wo, 0.0], np.float32)
        self.sample_kernel(
            self.ctx.queue, (n,), None, np.int32(n), self.I, self.F, wo4, self._in(u),
            self._in(choice), wi_buf, pdf_buf, again_buf,
        )  # fmt: skip
        for host, buf in ((wi, wi_buf), (pdf, pdf_buf), (again, again_buf)):
            self.cl.enqueue_copy(self.ctx.queue, host, buf)
        return wi, pdf, again

    def pdf(self, wo, wi):
        n = len(wi)
        pdf, pdf_buf = self._out(n)
        wo4 = np.array([*wo, 0.0], np.float32)
        self.pdf_kernel(
            self.ctx.queue, (n,), None, np.int32(n), self.I, self.F, wo4, self._in(wi), pdf_buf
        )
        self.cl.enqueue_copy(self.ctx.queue, pdf, pdf_buf)
        return pdf


@pytest.fixture(scope="module")
def alu():
    return MLVQBTF.from_directory(shared_material("alu"))


@pytest.fixture(scope="module")
def alu_sampler(cl_context, alu):
    return Sampler(cl_context, alu)


# Bins of the χ² test: equal solid angle in (cos θ, φ), a grid unrelated to the table's cells.
N_COS, N_PHI, SUB = 12, 24, 16  # SUB² midpoint points per bin integrate the pdf


def bin_grid_directions():
    """(N_COS·SUB · N_PHI·SUB, 3) midpoint directions of the fine sub-grid, row-major in
    (cos θ, φ), and the solid angle each stands for."""
    c = (np.arange(N_COS * SUB) + 0.5) / (N_COS * SUB)
    p = (np.arange(N_PHI * SUB) + 0.5) / (N_PHI * SUB) * 2 * math.pi
    cc, pp = np.meshgrid(c, p, indexing="ij")
    s = np.sqrt(1 - cc**2)
    w = np.stack([s * np.cos(pp), s * np.sin(pp), cc], -1).reshape(-1, 3)
    return w, (1.0 / (N_COS * SUB)) * (2 * math.pi / (N_PHI * SUB))


def bin_of(wi):
    cos_bin = np.minimum((np.clip(wi[:, 2], 0, 1) * N_COS).astype(int), N_COS - 1)
    phi = np.mod(np.arctan2(wi[:, 1], wi[:, 0]), 2 * math.pi)
    phi_bin = np.minimum((phi / (2 * math.pi) * N_PHI).astype(int), N_PHI - 1)
    return cos_bin * N_PHI + phi_bin


VIEWS = {
    "pole": (0.0, 0.0),
    "theta40": (40.0, 30.0),
    "theta70": (70.0, 200.0),
    "grazing": (87.0, 120.0),
}


@pytest.mark.parametrize("view", VIEWS)
def test_sampler_matches_its_pdf_chi_square(alu_sampler, view):
    """Pearson χ² of 10⁵ OpenCL samples against the kernel's own bsdf_pdf integrated per bin
    (16 × 16 midpoint points each, so the 288 bins see the pdf's jumps at table-cell edges
    finely). Bins expecting < 5 samples are pooled. Measured p = 0.09–0.76 over the four views;
    the same samples tested against plain cosine sampling's pdf give χ² ≈ 4,000–39,000
    (p = 0), so a sampler drawing from another density than bsdf_pdf states fails. Also: the
    pdf the sampler states is bsdf_pdf of its sample and equals the numpy reference (float32
    rounding)."""
    rng = np.random.default_rng(17)
    wo = direction(*VIEWS[view])
    n = 100_000
    u = rng.random((n, 2))
    wi, pdf, again = alu_sampler.sample(wo, u, rng.random(n))
    assert np.all(wi[:, 2] >= 0.0) and np.all(pdf > 0.0)
    np.testing.assert_allclose(pdf, again, rtol=1e-5)  # the same cell; d is unit to 1e-6
    table = btf_importance.importance_table(alu_sampler.btf)
    ref = table.pdf(wi.astype(np.float64), np.broadcast_to(wo, wi.shape))
    np.testing.assert_allclose(pdf, ref, rtol=1e-4)  # float32 maps vs float64
    observed = np.bincount(bin_of(wi), minlength=N_COS * N_PHI)
    grid, d_omega = bin_grid_directions()
    fine = alu_sampler.pdf(wo, grid).astype(np.float64) * d_omega
    per_bin = fine.reshape(N_COS, SUB, N_PHI, SUB).sum(axis=(1, 3)).ravel()
    expected = n * per_bin / per_bin.sum()
    low = expected < 5
    obs = np.append(observed[~low], observed[low].sum())
    exp = np.append(expected[~low], expected[low].sum())
    if exp[-1] == 0:
        obs, exp = obs[:-1], exp[:-1]
    stat = float(np.sum((obs - exp) ** 2 / exp))
    p = chi2.sf(stat, len(exp) - 1)
    assert p > 0.01, f"χ² = {stat:.1f} over {len(exp)} bins, p = {p:.2g}"


@pytest.mark.parametrize("view", VIEWS)
def test_pdf_is_normalised_and_positive(alu_sampler, view):
    """∫ pdf dω = 1 over the hemisphere within 10⁻³ (a 768 × 1536 midpoint rule in (cos θ, φ),
    measured error ≤ 10⁻⁴: table-cell edges crossing its cells); pdf > 0 at every
    direction with cos θi > 0, down to cos θi = 10⁻⁴ at the horizon (the cosine share), and 0
    below."""
    wo = direction(*VIEWS[view])
    nc, nphi = 768, 1536
    c = (np.arange(nc) + 0.5) / nc
    p = (np.arange(nphi) + 0.5) / nphi * 2 * math.pi
    cc, pp = np.meshgrid(c, p, indexing="ij")
    s = np.sqrt(1 - cc**2)
    wi = np.stack([s * np.cos(pp), s * np.sin(pp), cc], -1).reshape(-1, 3)
    pdf = alu_sampler.pdf(wo, wi).astype(np.float64)
    total = pdf.sum() / nc * (2 * math.pi / nphi)
    assert abs(total - 1.0) < 1e-3, total
    assert np.all(pdf > 0.0)
    ring = np.linspace(0, 2 * math.pi, 721)
    z = 1e-4
    horizon = np.stack([np.cos(ring), np.sin(ring), np.full_like(ring, z)], -1)
    assert np.all(alu_sampler.pdf(wo, horizon) > 0.0)
    below = horizon * [1.0, 1.0, -1.0]
    assert np.all(alu_sampler.pdf(wo, below) == 0.0)


def test_tables_only_for_measured_codecs(cl_context):
    """Analytic codecs keep their own sampling: no table in their packed header, and the
    sampler's output is bit-identical with the table code compiled out (HAS_BTF_IS 0), so their
    Sampled images cannot change. A Lambertian's pdf stays cos θ / π."""
    rng = np.random.default_rng(3)
    u, choice = rng.random((4096, 2)), rng.random(4096)
    wo = direction(50.0, 10.0)
    for btf in (GGXBTF((0.8, 0.7, 0.6), 0.3), LambertianBTF(0.7)):
        with_is, without = Sampler(cl_context, btf), Sampler(cl_context, btf, {"HAS_BTF_IS": 0})
        assert with_is.packed.ints.ravel()[INT_SLOT["f_importance"]] == 0
        a, b = with_is.sample(wo, u, choice), without.sample(wo, u, choice)
        assert all(np.array_equal(x, y) for x, y in zip(a, b, strict=True))
    lambert = with_is.sample(wo, u, choice)
    np.testing.assert_allclose(lambert[1], lambert[0][:, 2] / math.pi, rtol=1e-5)


def test_sampled_render_mean_unchanged(cl_context, alu):
    """The estimator stays unbiased: an alu sphere under a random environment rendered in the
    Sampled mode with the table and with cosine sampling has the same mean over the image
    within 1 % (measured: ≤ 0.15 % per channel over three seeds, the Monte Carlo noise of the
    two means at 256 samples × 432 pixels); a wrong pdf anywhere in the table biases it by far
    more."""
    from btf_addon.cl.renderer import CLRenderer

    rng = np.random.default_rng(11)
    env = Environment(rng.gamma(0.6, 1.0, size=(16, 32, 3)), rotation_z_rad=0.4)
    scene = Scene(
        [uv_sphere(1.0, segments=32, rings=16)],
        [Material(alu, uv_scale=2.0)],
        Camera(look_at((0.0, -4.0, 1.0), (0, 0, 0))),
        env,
    )
    renderer = CLRenderer(scene, 24, 18, cl_context, film=None)
    renderer.fixed_launch_split = True
    table = renderer.render_sampled(256, seed=1)[..., :3]
    renderer.importance_sampling = False
    cosine = renderer.render_sampled(256, seed=1)[..., :3]
    np.testing.assert_allclose(table.mean(axis=(0, 1)), cosine.mean(axis=(0, 1)), rtol=0.01)


def test_tables_packed_up_front_are_not_packed_again(cl_context, alu):
    """F12 in the Sampled mode makes its renderer with ``importance_tables``: the first
    render_sampled then uploads nothing (the same buffers before and after; packing twice cost
    the demo's F12 15 ms), and the direct kernel, which never reads the tables, draws the same
    passes as from tables packed without them."""
    from btf_addon.cl.renderer import CLRenderer

    scene = Scene(
        [uv_sphere(1.0, segments=24, rings=12)],
        [Material(alu, uv_scale=2.0)],
        Camera(look_at((0.0, -4.0, 1.0), (0, 0, 0))),
        Environment(np.full((8, 16, 3), 0.5, np.float32)),
    )
    plain = CLRenderer(scene, 16, 12, cl_context, film=None)
    with_tables = CLRenderer(scene, 16, 12, cl_context, film=None, importance_tables=True)
    uploaded = [with_tables.ints, with_tables.floats, with_tables.material_offsets]
    with_tables.render_sampled(4, seed=1)
    now = [with_tables.ints, with_tables.floats, with_tables.material_offsets]
    assert all(a is b for a, b in zip(now, uploaded, strict=True))
    plain_tables = plain.ints
    plain.render_sampled(4, seed=1)
    assert plain.ints is not plain_tables  # without it the tables are packed on the way
    light = VirtualLights(np.array([[0.3, -0.5, 0.8]]), np.ones((1, 3)), np.ones(1))
    a, b = (
        CLRenderer(scene, 16, 12, cl_context, film=None).render_direct(light),
        with_tables.render_direct(light),
    )
    for name in ("combined", "depth", "normal", "uv"):
        np.testing.assert_array_equal(getattr(a, name), getattr(b, name))
