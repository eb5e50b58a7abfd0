/* BTF evaluation from the packed table layout shared with the GLSL back end
 * (btf_addon/core/packed.py writes it; shaders/btf_*_lib.glsl read the same layout). One material
 * is two streams: `I` (integers stored exactly as floats) and `F` (floats), each starting with a
 * header of sizes and table offsets. Reference for every step: btf_addon/core (numpy). */
#ifndef BTF_PACKED_H
#define BTF_PACKED_H

#include "btf_builtins.h"
#include "btf_colour.h"

#define ITAB(i) ((int)I[(i)])
#define FTAB(i) (F[(i)])

/* Header slots (H_*: integer stream, F_*: float stream) and codec ids (CODEC_*) are not written
 * here: btf_addon/core/packed.py defines the layout once and cl/programs.py passes it to every
 * build as -D options (packed.defines()). */
#if !defined(H_CODEC) || !defined(F_VALUE_SCALE) || !defined(CODEC_MLVQ)
#error "packed-layout defines missing: build through btf_addon/cl/programs.py build_program"
#endif

typedef __global const float *Stream;

/* Codec variants (btf_addon/scene/analysis.py): a program compiles only the decoders of the
 * codecs its scene has; undefined means all (eval_btf, tests). */
#ifndef HAS_MLVQ
#define HAS_MLVQ 1
#endif
#ifndef HAS_DENSE
#define HAS_DENSE 1
#endif
#ifndef HAS_SVD
#define HAS_SVD 1
#endif
#ifndef HAS_ANALYTIC
#define HAS_ANALYTIC 1
#endif

#define BTF_CLAMPF(x, lo, hi) BTF_FMIN(BTF_FMAX((x), (lo)), (hi))
#define BTF_IMIN(a, b) ((a) < (b) ? (a) : (b))
#define BTF_IMAX(a, b) ((a) > (b) ? (a) : (b))
#define BTF_DEG(rad) ((rad) * (180.0f / M_PI_F))
#define BTF_RAD(deg) ((deg) * (M_PI_F / 180.0f))

inline float2 btf_ld2(Stream p)
{
  return (float2)(p[0], p[1]);
}

inline float3 btf_ld3(Stream p)
{
  return (float3)(p[0], p[1], p[2]);
}

inline float4 btf_ld4(Stream p)
{
  return (float4)(p[0], p[1], p[2], p[3]);
}

inline float btf_mod(float x, float m)
{
  return x - m * BTF_FLOOR(x / m);
}

inline void btf_uniform_index(float x, float step, int max_index, int *i, float *w)
{
  int k = BTF_IMIN(BTF_IMAX((int)(x / step), 0), max_index);
  *i = k;
  *w = (x - k * step) / step;
}

/* --- MLVQ --------------------------------------------------------------------------------- */
/* Where the time goes (docs/accuracy.md "BTFbase decoding"): a decode is 4 (φ, θ) corners ×
 * 2 α nodes = 8 luminance curves and 8 colour curves, each behind a chain of dependent table
 * reads, and the light angles. So the chain is flattened (f_mlvq43: texel → (slot, φ, θ) entry
 * → (α) curve → β samples), the per-decode constants are computed once (the Hermite step's
 * three weights, every table offset), each curve is one 3-float read, and the angles use
 * branch-free polynomials instead of PoCL's scalar libm (one sincos, two atan2). Same
 * arithmetic as btf_addon/core/mlvq.py up to float rounding (tests/kernels/test_decode_speed.py
 * states the tolerance). */

/* atan(a) for a in [0, 1] in radians: odd minimax-fitted polynomial, |error| < 1.1e-7 rad
 * (float32's own rounding of atan near 1 is 6e-8). */
inline float btf_atan_unit(float a)
{
  float s = a * a;
  float p = -0.004054556135088205f;
  p = p * s + 0.02186293713748455f;
  p = p * s - 0.05591233819723129f;
  p = p * s + 0.09642201662063599f;
  p = p * s - 0.13908633589744568f;
  p = p * s + 0.19946567714214325f;
  p = p * s - 0.33329862356185913f;
  p = p * s + 0.9999993443489075f;
  return a * p;
}

/* atan2(y, x) in degrees for x >= 0 (the two angles of the decode): in [-90, 90], branch-free
 * so that work-items stay in step; (0, 0) gives 0. */
inline float btf_atan2_deg_xpos(float y, float x)
{
  float ay = BTF_FABS(y);
  float hi = BTF_FMAX(ay, x), lo = BTF_FMIN(ay, x);
  float a = btf_atan_unit(hi > 0.0f ? lo / hi : 0.0f);
  a = ay > x ? M_PI_2_F - a : a;
  return BTF_COPYSIGN(BTF_DEG(a), y);
}

/* sin and cos of an angle in degrees: reduced exactly to [-45°, 45°] in degrees, then Taylor
 * polynomials (truncation < 3e-9 there), the quadrant by selects. */
inline float btf_sincos_deg(float deg, float *c)
{
  float k = BTF_RINT(deg / 90.0f);
  float x = BTF_RAD(deg - 90.0f * k);
  float x2 = x * x;
  float s = x * (1.0f + x2 * (-1.0f / 6.0f + x2 * (1.0f / 120.0f + x2 * (-1.0f / 5040.0f +
                                                                         x2 / 362880.0f))));
  float co = 1.0f + x2 * (-0.5f + x2 * (1.0f / 24.0f + x2 * (-1.0f / 720.0f +
                                                             x2 * (1.0f / 40320.0f -
                                                                   x2 / 3628800.0f))));
  int q = ((int)k) & 3;
  float sq = (q == 0) ? s : (q == 1) ? co : (q == 2) ? -s : -co;
  float cq = (q == 0) ? co : (q == 1) ? -s : (q == 2) ? -co : s;
  *c = cq;
  return sq;
}

/* The Hermite step of mlvq_pdf1 (core/mlvq.py _pdf1) as three weights on p[i-1], p[i], p[i+1]:
 * left tangent 0.5·(p1 − p[i−1]) (p1 − p0 at i = 0), right 0.5·(p1 − p0) (p1 − p0 at the last
 * interval). The same for every curve of one decode. */
inline float3 mlvq_hermite_weights(int i, float w, int n_beta)
{
  float t2 = w * w, t3 = t2 * w;
  float h01 = -2.0f * t3 + 3.0f * t2;
  float h00 = 1.0f - h01;
  float h11 = t3 - t2;
  float h10 = h11 - t2 + w;
  float gm = (i == n_beta - 2) ? 1.0f : 0.5f;
  /* m0 = p1 − p0 at i = 0 (edge), else 0.5·(p1 − p[i−1]): a select, not a branch */
  float3 inner = (float3)(-0.5f * h10, h00 - gm * h11, h01 + 0.5f * h10 + gm * h11);
  float3 edge = (float3)(0.0f, h00 - h10 - gm * h11, h01 + h10 + gm * h11);
  return i == 0 ? edge : inner;
}

typedef struct {
  int n_beta, n_alpha, n_theta, n_phi;
  int ib, ia, it, ip, ip1;
  float wa, wt, wp, wb;
  float3 hw; /* mlvq_hermite_weights(ib, wb) */
  /* table offsets, read once */
  int pdf2_col, pdf1, f2, fab, f43;
} MLVQCell;

/* Luminance and colour (one 2D function at (α, β), already scaled) → RGB. */
inline float3 mlvq_rgb(Stream I, float lum, float2 cbcr)
{
#if defined(MLVQ_HDR) && !MLVQ_HDR /* an LDR material's program: no LogLuv path to step over */
  return btf_ycbcr_to_rgb(lum, cbcr.x, cbcr.y);
#endif
  if (ITAB(H_HDR)) {
    return btf_logluv_to_rgb(lum, cbcr.x, cbcr.y);
  }
  return btf_ycbcr_to_rgb(lum, cbcr.x, cbcr.y);
}

/* Everything of a decode that does not depend on the texel: indices and weights of the
 * angles, table offsets. Angles in degrees, theta <= 90, and wi the unit light direction of
 * (theta_i, phi_i). A bilinear lookup computes it once for its four texels. */
__attribute__((always_inline)) inline MLVQCell mlvq_cell(Stream I, Stream F, float3 wi, float theta_i, float phi_i,
                          float theta_v, float phi_v)
{
  MLVQCell c;
  c.n_beta = ITAB(H_N_BETA);
  c.n_alpha = ITAB(H_N_ALPHA);
  c.n_theta = ITAB(H_N_THETA);
  c.n_phi = ITAB(H_N_PHI);
  float view_phi = btf_mod(360.0f - phi_v, 360.0f);
  /* The original rotates the light by φ' = φv − φi − 90° and takes x = cos φ'·sin θi,
   * y = sin φ'·sin θi: in terms of wi = (sin θi cos φi, sin θi sin φi, cos θi) that is
   * x = sin φv·wi.x − cos φv·wi.y, y = −(cos φv·wi.x + sin φv·wi.y). */
  float cos_pv;
  float sin_pv = btf_sincos_deg(phi_v, &cos_pv);
  float bx = sin_pv * wi.x - cos_pv * wi.y, by = -(cos_pv * wi.x + sin_pv * wi.y);
  bx = BTF_CLAMPF(bx, -1.0f, 1.0f);

  /* (x, y, wi.z) is wi turned about the normal, a unit vector: cos β = √(y² + z²) without
   * the cancellation of √(1 − x²), and β, α as atan2 stay accurate at grazing light, where the
   * original's asin in float32 loses half the digits (β → ±90°). */
  float cos_beta = BTF_SQRT(by * by + wi.z * wi.z);
  float beta = btf_atan2_deg_xpos(bx, cos_beta);
  float alpha = cos_beta < 1e-3f ? 0.0f : btf_atan2_deg_xpos(by, BTF_FMAX(wi.z, 0.0f));

  if (ITAB(H_COS_BETA)) { /* samples uniform in sin β: the index straight from x = sin β */
    c.ib = BTF_IMIN(BTF_IMAX((int)((bx + 1.0f) * 0.5f * (c.n_beta - 1)), 0), c.n_beta - 2);
    float2 b = btf_ld2(F + ITAB(H_F_BETA) + c.ib);
    c.wb = (beta - b.x) / (b.y - b.x);
  }
  else {
    btf_uniform_index(beta + 90.0f, 180.0f / (c.n_beta - 1), c.n_beta - 2, &c.ib, &c.wb);
  }
  btf_uniform_index(alpha + 90.0f, 180.0f / (c.n_alpha - 1), c.n_alpha - 2, &c.ia, &c.wa);
  btf_uniform_index(BTF_CLAMPF(theta_v, 0.0f, 90.0f), 90.0f / (c.n_theta - 1), c.n_theta - 2,
                    &c.it, &c.wt);
  btf_uniform_index(BTF_CLAMPF(view_phi, 0.0f, 360.0f), 360.0f / c.n_phi, c.n_phi - 1, &c.ip,
                    &c.wp);
  c.ip1 = c.ip + 1 < c.n_phi ? c.ip + 1 : 0; /* φ wraps: the last slice blends into slice 0 */
  c.hw = mlvq_hermite_weights(c.ib, c.wb, c.n_beta);
  c.pdf2_col = ITAB(H_PDF2_COLOURS);
  c.pdf1 = ITAB(H_F_PDF1);
  c.f2 = ITAB(H_F_MLVQ2);
  c.fab = ITAB(H_F_MLVQ_AB);
  c.f43 = ITAB(H_F_MLVQ43);
  return c;
}

/* i in [-n, 2n) → i mod n without integer division (texel wrapping with the row/column
 * offsets of the material). */
inline int btf_wrap(int i, int n)
{
  i = i < 0 ? i + n : i;
  return i >= n ? i - n : i;
}

/* A decode's table walk, level by level: (1) the texel; (2) the two (slot, φ) rows of
 * (θ, θ+1) entries; (3) the four 2D functions' (scale, curve) pairs and colour slices; (4) the
 * eight curves and eight colour pairs. Each level's reads are issued together before any is
 * used, so its cache misses overlap instead of following one another: a decode is bound by
 * these misses, not by its arithmetic (docs/accuracy.md). mlvq_texel runs the levels for one
 * texel; eval_mlvq (kernels/btf_eval.cl) runs each level for a batch of queries before the
 * next, so the misses of several queries overlap too. */
typedef struct {
  MLVQCell c;
  int slot6;
  float scale6;
  float4 scale;     /* per 2D function: s4·s3 × its (φ, θ) weight */
  int4 lum_fn, col_fn;
  float4 s[4];      /* per 2D function: (scale, curve) at α's two nodes */
  float2 k[4];      /* per 2D function: colour slices at α's two nodes */
} MLVQWalk;

/* Level 1: the texel holding uv → pdf6 (scale, slot). */
inline void mlvq_walk_texel(Stream I, Stream F, MLVQWalk *w, float2 uv)
{
  int width = ITAB(H_WIDTH), height = ITAB(H_HEIGHT);
  /* floor(frac(u)·width) lies in [0, width] (width when frac rounds up), the offsets in
   * [0, width): two conditional steps wrap it. */
  int x = btf_wrap((int)BTF_FLOOR(btf_mod(uv.x, 1.0f) * width) - ITAB(H_COLS_OFFSET), width);
  int y = btf_wrap((int)BTF_FLOOR(btf_mod(uv.y, 1.0f) * height) - ITAB(H_ROWS_OFFSET), height);
  float2 t6 = btf_ld2(F + ITAB(H_F_MLVQ6) + 2 * (y * width + x)); /* (pdf6 scale, slot + 1) */
  /* A texel not stored (slot 0 in the file) decodes slot 0 with weight 0: no branch, so the
   * work-items of a group stay in step. */
  w->slot6 = BTF_IMAX((int)t6.y - 1, 0);
  w->scale6 = t6.y >= 1.0f ? t6.x : 0.0f;
}

/* Level 2: (s4·s3, luminance fn, colour fn, 0) at θ and θ+1 for φ and φ+1: two 8-float reads */
inline void mlvq_walk_rows(Stream F, MLVQWalk *w)
{
  const MLVQCell *c = &w->c;
  Stream r0 = F + c->f43 + 4 * ((w->slot6 * c->n_phi + c->ip) * c->n_theta + c->it);
  Stream r1 = F + c->f43 + 4 * ((w->slot6 * c->n_phi + c->ip1) * c->n_theta + c->it);
  float4 e00 = btf_ld4(r0), e01 = btf_ld4(r0 + 4), e10 = btf_ld4(r1), e11 = btf_ld4(r1 + 4);
  w->scale = (float4)(e00.x, e01.x, e10.x, e11.x) *
             ((float4)(1.0f - c->wp, 1.0f - c->wp, c->wp, c->wp) *
              (float4)(1.0f - c->wt, c->wt, 1.0f - c->wt, c->wt));
  w->lum_fn = (int4)((int)e00.y, (int)e01.y, (int)e10.y, (int)e11.y);
  w->col_fn = (int4)((int)e00.z, (int)e01.z, (int)e10.z, (int)e11.z);
}

/* Level 3: per 2D function, (scale, curve) at the α interval's two nodes and its two colour
 * slices. */
inline void mlvq_walk_functions(Stream I, Stream F, MLVQWalk *w)
{
  const MLVQCell *c = &w->c;
  int4 f2 = c->f2 + 2 * (w->lum_fn * c->n_alpha + c->ia);
  int4 ci = c->pdf2_col + w->col_fn * c->n_alpha + c->ia;
  w->s[0] = btf_ld4(F + f2.s0);
  w->s[1] = btf_ld4(F + f2.s1);
  w->s[2] = btf_ld4(F + f2.s2);
  w->s[3] = btf_ld4(F + f2.s3);
  w->k[0] = btf_ld2(I + ci.s0);
  w->k[1] = btf_ld2(I + ci.s1);
  w->k[2] = btf_ld2(I + ci.s2);
  w->k[3] = btf_ld2(I + ci.s3);
}

/* Level 4: the eight curves at β (one 3-float read each: p[i−1] is read at i = 0 too, with
 * weight 0; the float stream's header precedes every table, so the read stays inside) and the
 * eight (Cb, Cr) pairs at β's two nodes → the raw RGB. */
__attribute__((always_inline)) inline float3 mlvq_walk_rgb(Stream I, Stream F, const MLVQWalk *w)
{
  const MLVQCell *c = &w->c;
  int pdf1 = c->pdf1 + c->ib - 1, ab = c->fab + 2 * c->ib, nb = c->n_beta;
  float wa0 = 1.0f - c->wa, wb0 = 1.0f - c->wb;
  float3 rgb = (float3)(0.0f);
  float sc[4] = {w->scale.s0, w->scale.s1, w->scale.s2, w->scale.s3};
  for (int j = 0; j < 4; j++) { /* unrolled: the 16 reads are independent */
    float4 s = w->s[j];
    float2 k = w->k[j];
    float3 p0 = btf_ld3(F + pdf1 + (int)s.y * nb) * c->hw;
    float3 p1 = btf_ld3(F + pdf1 + (int)s.w * nb) * c->hw;
    float lum = wa0 * s.x * (p0.x + p0.y + p0.z) + c->wa * s.z * (p1.x + p1.y + p1.z);
    float4 a0 = btf_ld4(F + ab + 2 * (int)k.x * nb), a1 = btf_ld4(F + ab + 2 * (int)k.y * nb);
    float2 cbcr = wa0 * (a0.xy * wb0 + a0.zw * c->wb) + c->wa * (a1.xy * wb0 + a1.zw * c->wb);
    rgb += mlvq_rgb(I, lum, cbcr) * sc[j];
  }
  rgb *= w->scale6;
  if (ITAB(H_HDR)) {
    rgb /= FTAB(F_HDR_VALUE);
  }
  return rgb;
}

/* The original decoder's raw RGB at the texel holding uv, for the cell's angles. */
inline float3 mlvq_texel(Stream I, Stream F, const MLVQCell *cp, float2 uv)
{
  MLVQWalk w;
  w.c = *cp;
  mlvq_walk_texel(I, F, &w, uv);
  mlvq_walk_rows(F, &w);
  mlvq_walk_functions(I, F, &w);
  return mlvq_walk_rgb(I, F, &w);
}

/* Angles in degrees, theta <= 90, and wi the unit light direction of (theta_i, phi_i): the
 * original decoder's raw RGB. */
inline float3 mlvq_decode(Stream I, Stream F, float2 uv, float3 wi, float theta_i, float phi_i,
                          float theta_v, float phi_v)
{
  MLVQCell c = mlvq_cell(I, F, wi, theta_i, phi_i, theta_v, phi_v);
  return mlvq_texel(I, F, &c, uv);
}

/* --- dense -------------------------------------------------------------------------------- */

/* The two θ rings around ``theta`` (clamped to the measured range) → r0, r1 and the weight of
 * r1: the ring step of the dense and svd codecs' interpolation (core/grid.py). */
inline float ring_pair(Stream F, int theta_off, int n_rings, float theta, int *r0, int *r1)
{
  theta = clamp(theta, FTAB(theta_off), FTAB(theta_off + n_rings - 1));
  *r0 = 0;
  for (int r = 1; r < n_rings - 1; r++) {
    if (FTAB(theta_off + r) <= theta) {
      *r0 = r;
    }
  }
  *r1 = *r0;
  if (n_rings < 2) {
    return 0.0f;
  }
  *r1 = *r0 + 1;
  return (theta - FTAB(theta_off + *r0)) / (FTAB(theta_off + *r1) - FTAB(theta_off + *r0));
}

inline void ring_weights(Stream I, Stream F, int theta_off, int offsets_off, int n_rings,
                         float theta, float phi, int idx[4], float w[4])
{
  int r0, r1;
  float wt = ring_pair(F, theta_off, n_rings, theta, &r0, &r1);
  for (int k = 0; k < 2; k++) {
    int ring = k ? r1 : r0;
    float ring_w = k ? wt : 1.0f - wt;
    int start = ITAB(offsets_off + ring);
    int n = ITAB(offsets_off + ring + 1) - start;
    float pos = btf_mod(phi, 360.0f) / (360.0f / n);
    int s0 = ((int)floor(pos)) % n;
    float wp = pos - floor(pos);
    idx[2 * k] = start + s0;
    idx[2 * k + 1] = start + (s0 + 1) % n;
    w[2 * k] = ring_w * (1.0f - wp);
    w[2 * k + 1] = ring_w * wp;
  }
}

inline float ring_sample_phi(Stream I, int offsets_off, int n_rings, int i)
{
  for (int r = 0; r < n_rings; r++) {
    int start = ITAB(offsets_off + r), end = ITAB(offsets_off + r + 1);
    if (i < end) {
      return (float)(i - start) * 360.0f / (float)(end - start);
    }
  }
  return 0.0f;
}

inline float3 dense_evaluate(Stream I, Stream F, float2 uv, float theta_i, float phi_i,
                             float theta_v, float phi_v)
{
  int width = ITAB(H_WIDTH), height = ITAB(H_HEIGHT), n_lights = ITAB(H_N_LIGHTS);
  int x = ((int)floor(btf_mod(uv.x, 1.0f) * width)) % width;
  int y = ((int)floor(btf_mod(uv.y, 1.0f) * height)) % height;
  int vi[4], li[4];
  float vw[4], lw[4];
  int n_view_rings = ITAB(H_N_VIEW_RINGS), n_light_rings = ITAB(H_N_LIGHT_RINGS);
  ring_weights(I, F, ITAB(H_F_VIEW_THETA), ITAB(H_VIEW_OFFSETS), n_view_rings, theta_v, phi_v,
               vi, vw);
  float3 sum = (float3)(0.0f);
  int data = ITAB(H_F_DATA);
  for (int a = 0; a < 4; a++) {
    if (vw[a] <= 0.0f) {
      continue;
    }
    float view_phi = ring_sample_phi(I, ITAB(H_VIEW_OFFSETS), n_view_rings, vi[a]);
    ring_weights(I, F, ITAB(H_F_LIGHT_THETA), ITAB(H_LIGHT_OFFSETS), n_light_rings, theta_i,
                 phi_i - phi_v + view_phi, li, lw);
    for (int b = 0; b < 4; b++) {
      int base = data + (((vi[a] * n_lights + li[b]) * height + y) * width + x) * 3;
      sum += vw[a] * lw[b] * (float3)(FTAB(base), FTAB(base + 1), FTAB(base + 2));
    }
  }
  float last = FTAB(ITAB(H_F_LIGHT_THETA) + n_light_rings - 1);
  if (theta_i > last) {
    sum *= cos(radians(theta_i)) / cos(radians(last));
  }
  return sum;
}

#include "btf_svd.h"

/* --- analytic and dispatch ---------------------------------------------------------------- */

inline float ggx_lambda(float alpha2, float c)
{
  float c2 = fmax(c, 1e-6f);
  c2 *= c2;
  return 0.5f * (-1.0f + sqrt(1.0f + alpha2 * fmax(1.0f / c2 - 1.0f, 0.0f)));
}

/* GGX normal distribution D(m) for cos θm (α² given). */
inline float ggx_d(float alpha2, float cos_m)
{
  float denom = 1.0f + (alpha2 - 1.0f) * cos_m * cos_m;
  return alpha2 / (M_PI_F * denom * denom);
}

/* wi, wo: unit tangent-frame directions with z >= 0; angles in degrees of the same directions. */
inline float3 btf_evaluate(Stream I, Stream F, float2 uv, float3 wi, float3 wo, float theta_i,
                           float phi_i, float theta_v, float phi_v)
{
  int codec = ITAB(H_CODEC);
#if HAS_MLVQ
  if (codec == CODEC_MLVQ) {
    return mlvq_decode(I, F, uv, wi, theta_i, phi_i, theta_v, phi_v) * FTAB(F_VALUE_SCALE);
  }
#endif
#if HAS_DENSE
  if (codec == CODEC_DENSE) {
    return dense_evaluate(I, F, uv, theta_i, phi_i, theta_v, phi_v);
  }
#endif
#if HAS_SVD
  if (codec == CODEC_SVD) {
    return svd_evaluate(I, F, uv, theta_i, phi_i, theta_v, phi_v) * FTAB(F_VALUE_SCALE);
  }
#endif
#if !HAS_ANALYTIC
  return (float3)(0.0f); /* not reached: the scene has no analytic material */
#else
  float3 albedo = (float3)(FTAB(F_ALBEDO), FTAB(F_ALBEDO + 1), FTAB(F_ALBEDO + 2));
  if (codec == CODEC_LAMBERTIAN) {
    return albedo * (fmax(wi.z, 0.0f) / M_PI_F);
  }
  float alpha2 = FTAB(F_ALPHA2);
  float3 h = wi + wo;
  float h_len = length(h);
  float cos_h = h_len > 1e-12f ? h.z / h_len : 0.0f;
  float g = 1.0f / (1.0f + ggx_lambda(alpha2, wi.z) + ggx_lambda(alpha2, wo.z));
  float ggx = ggx_d(alpha2, cos_h) * g / (4.0f * fmax(wo.z, 1e-6f));
  if (codec == CODEC_GGX) {
    return albedo * ggx;
  }
  /* CODEC_PRINCIPLED, as PrincipledBTF in btf_addon/core/analytic.py */
  float metallic = FTAB(F_METALLIC), sigma = FTAB(F_DIFFUSE_ROUGHNESS);
  float f0d = FTAB(F_SPECULAR_F0);
  float3 f0 = f0d + (albedo - f0d) * metallic;
  float cos_d = h_len > 1e-12f ? clamp(dot(h, wo) / h_len, 0.0f, 1.0f) : 0.0f;
  float3 fresnel = f0 + (1.0f - f0) * pown(1.0f - cos_d, 5);
  float s = dot(wi, wo) - wi.z * wo.z;
  float a = 1.0f / (M_PI_F + (M_PI_F / 2.0f - 2.0f / 3.0f) * sigma);
  float ci_over_t = s > 0.0f ? wi.z / fmax(fmax(wi.z, wo.z), 1e-6f) : wi.z;
  float on = a * wi.z + sigma * a * s * ci_over_t;
  float weight = (1.0f - metallic) * (1.0f - (f0d + (1.0f - f0d) *
                                               pown(1.0f - clamp(wo.z, 0.0f, 1.0f), 5)));
  return weight * albedo * on + fresnel * ggx;
#endif
}

inline float2 btf_theta_phi_deg(float3 d)
{
  float phi = degrees(atan2(d.y, d.x));
  return (float2)(degrees(acos(clamp(d.z, -1.0f, 1.0f))), phi < 0.0f ? phi + 360.0f : phi);
}

/* btf_evaluate with spatial filtering (btf_addon/core/mapping.py filtered_evaluate):
 * FILTER_LINEAR decodes the 4 texels around uv at their centres and blends them bilinearly,
 * wrapping around the tile; FILTER_NEAREST (and one-texel BTFs) decode once at uv. */
inline float3 btf_filtered(Stream I, Stream F, int filter, float2 uv, float3 wi, float3 wo)
{
  float2 light = btf_theta_phi_deg(wi), view = btf_theta_phi_deg(wo);
  int width = ITAB(H_WIDTH), height = ITAB(H_HEIGHT);
  if (filter != FILTER_LINEAR || width * height <= 1) {
    return btf_evaluate(I, F, uv, wi, wo, light.x, light.y, view.x, view.y);
  }
  float2 size = (float2)((float)width, (float)height);
  float2 s = (uv - floor(uv)) * size - 0.5f; /* mod first: large uv keep their fraction */
  float2 i0 = floor(s);
  float2 f = s - i0;
  float x0 = btf_mod(i0.x, size.x), y0 = btf_mod(i0.y, size.y);
  float x1 = btf_mod(x0 + 1.0f, size.x), y1 = btf_mod(y0 + 1.0f, size.y);
  float3 sum = (float3)(0.0f);
#if HAS_MLVQ
  if (ITAB(H_CODEC) == CODEC_MLVQ) {
    /* the four texels share the angles' work, and walk the tables level by level together so
     * that their cache misses overlap (MLVQWalk) */
    MLVQWalk walk[4];
    for (int k = 0; k < 4; k++) {
      walk[k].c = k ? walk[0].c : mlvq_cell(I, F, wi, light.x, light.y, view.x, view.y);
      float x = (k & 1) ? x1 : x0, y = (k & 2) ? y1 : y0;
      mlvq_walk_texel(I, F, &walk[k], (float2)((x + 0.5f) / size.x, (y + 0.5f) / size.y));
    }
    for (int k = 0; k < 4; k++) {
      mlvq_walk_rows(F, &walk[k]);
    }
    for (int k = 0; k < 4; k++) {
      mlvq_walk_functions(I, F, &walk[k]);
    }
    for (int k = 0; k < 4; k++) {
      float w = ((k & 1) ? f.x : 1.0f - f.x) * ((k & 2) ? f.y : 1.0f - f.y);
      sum += w * (mlvq_walk_rgb(I, F, &walk[k]) * FTAB(F_VALUE_SCALE));
    }
    return sum;
  }
#endif
  for (int k = 0; k < 4; k++) {
    float x = (k & 1) ? x1 : x0, y = (k & 2) ? y1 : y0;
    float w = ((k & 1) ? f.x : 1.0f - f.x) * ((k & 2) ? f.y : 1.0f - f.y);
    float2 centre = (float2)((x + 0.5f) / size.x, (y + 0.5f) / size.y);
    sum += w * btf_evaluate(I, F, centre, wi, wo, light.x, light.y, view.x, view.y);
  }
  return sum;
}

#endif
