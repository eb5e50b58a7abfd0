/* BTF evaluation from the packed table layout shared with the GLSL back end
 * (btf_addon/core/codecs/packed.py writes it; shaders/btf_*_lib.glsl read the same layout). One material
 * is two streams: `I` (integers stored exactly as floats) and `F` (floats), each starting with a
 * header of sizes and table offsets. Reference for every step: btf_addon/core (numpy). */
#ifndef BTF_PACKED_H
#define BTF_PACKED_H

#include "btf_builtins.h"
#include "btf_colour.h"

#define ITAB(i) ((int)I[(i)])
#define FTAB(i) (F[(i)])

/* Header slots (H_*: integer stream, F_*: float stream) and codec ids (CODEC_*) are not written
 * here: btf_addon/core/codecs/packed.py defines the layout once and cl/programs.py passes it to every
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

/* Row i of an (n, 3) float output, by plain stores: PoCL's vstore3 is a call. */
inline void btf_st3(__global float *out, int i, float3 v)
{
  out[3 * i] = v.x;
  out[3 * i + 1] = v.y;
  out[3 * i + 2] = v.z;
}

inline float btf_mod(float x, float m)
{
  return x - m * BTF_FLOOR(x / m);
}

/* --- MLVQ --------------------------------------------------------------------------------- */
/* Where the time goes (docs/accuracy.md "BTFbase decoding"): a decode is 4 (φ, θ) corners ×
 * 2 α nodes = 8 luminance curves and 8 colour curves, each behind a chain of dependent table
 * reads, and the light angles. So the chain is flattened (f_mlvq43: texel → (slot, φ, θ) entry
 * → (α) curve → β samples), the per-decode constants are computed once (the Hermite step's
 * three weights, every table offset), each curve is one 3-float read, and the angles use
 * branch-free polynomials instead of PoCL's scalar libm (one sincos, two atan2). Same
 * arithmetic as btf_addon/core/codecs/mlvq.py up to float rounding (tests/kernels/test_decode_speed.py
 * states the tolerance). */

/* The angle maths (atan2, sincos, the four indices and the Hermite weights), for float here;
 * eval_mlvq includes it again for float8 (kernels/btf_eval.cl). */
#define BTF_T float
#define BTF_I int
#define BTF_N(name) name
#define BTF_TMAX(a, b) BTF_FMAX((a), (b))
#define BTF_TMIN(a, b) BTF_FMIN((a), (b))
#define BTF_TABS(x) BTF_FABS(x)
#define BTF_TSQRT(x) BTF_SQRT(x)
#define BTF_TRINT(x) BTF_RINT(x)
#define BTF_TFLOOR(x) BTF_FLOOR(x)
#define BTF_TCOPYSIGN(a, b) BTF_COPYSIGN((a), (b))
#define BTF_TOINT(x) ((int)(x))
#define BTF_TOFLOAT(i) ((float)(i))
#define BTF_TLOAD(p, i) ((p)[(i)])
#include "btf_angles.inc"
#undef BTF_T
#undef BTF_I
#undef BTF_N
#undef BTF_TMAX
#undef BTF_TMIN
#undef BTF_TABS
#undef BTF_TSQRT
#undef BTF_TRINT
#undef BTF_TFLOOR
#undef BTF_TCOPYSIGN
#undef BTF_TOINT
#undef BTF_TOFLOAT
#undef BTF_TLOAD

typedef struct {
  int n_beta, n_alpha, n_theta, n_phi;
  int ib, ia, it, ip, ip1;
  float wa, wt, wp, wb;
  float3 hw; /* mlvq_hermite_weights(ib, wb) */
  /* table offsets, read once */
  int pdf2_col, pdf1, f2, fab, f43;
} MLVQCell;

/* A cell from its angles (mlvq_angles, for one query or one lane of eight) and the material's
 * sizes and table offsets, read once. */
__attribute__((always_inline)) inline MLVQCell mlvq_cell_of(Stream I, MLVQAngles a)
{
  MLVQCell c;
  c.n_beta = ITAB(H_N_BETA);
  c.n_alpha = ITAB(H_N_ALPHA);
  c.n_theta = ITAB(H_N_THETA);
  c.n_phi = ITAB(H_N_PHI);
  c.ib = a.ib;
  c.ia = a.ia;
  c.it = a.it;
  c.ip = a.ip;
  c.ip1 = a.ip1;
  c.wb = a.wb;
  c.wa = a.wa;
  c.wt = a.wt;
  c.wp = a.wp;
  c.hw = (float3)(a.hm, a.h0, a.hp);
  c.pdf2_col = ITAB(H_PDF2_COLOURS);
  c.pdf1 = ITAB(H_F_PDF1);
  c.f2 = ITAB(H_F_MLVQ2);
  c.fab = ITAB(H_F_MLVQ_AB);
  c.f43 = ITAB(H_F_MLVQ43);
  return c;
}

/* Everything of a decode that does not depend on the texel: indices and weights of the
 * angles, table offsets. Angles in degrees, theta <= 90, and wi the unit light direction of
 * (theta_i, phi_i). A bilinear lookup computes it once for its four texels. */
__attribute__((always_inline)) inline MLVQCell mlvq_cell(Stream I, Stream F, float3 wi,
                                                         float theta_v, float phi_v)
{
  return mlvq_cell_of(I, mlvq_angles(I, F, wi.x, wi.y, wi.z, theta_v, phi_v));
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
  float4 lanes[14]; /* level 4's reads, the four functions as lanes (mlvq_walk_curves) */
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

/* One float of each of the four 2D functions' reads, as the lanes of a float4. */
#define MLVQ_LANES(p, o) ((float4)((p)[0][o], (p)[1][o], (p)[2][o], (p)[3][o]))

/* Level 4, the reads: the eight curves at β (one 3-float read each: p[i−1] is read at i = 0
 * too, with weight 0; the float stream's header precedes every table, so the read stays inside)
 * and the eight (Cb, Cr) pairs at β's two nodes, kept in the walk with the four 2D functions as
 * the lanes of float4s. A step of its own, so that a batch's misses are all in flight before
 * any of its arithmetic (docs/accuracy.md). */
inline void mlvq_walk_curves(Stream F, MLVQWalk *w)
{
  const MLVQCell *c = &w->c;
  int pdf1 = c->pdf1 + c->ib - 1, ab = c->fab + 2 * c->ib, nb = c->n_beta;
  Stream c0[4], c1[4], a0[4], a1[4];
  for (int j = 0; j < 4; j++) { /* the 16 reads' addresses */
    c0[j] = F + pdf1 + (int)w->s[j].y * nb;
    c1[j] = F + pdf1 + (int)w->s[j].w * nb;
    a0[j] = F + ab + 2 * (int)w->k[j].x * nb;
    a1[j] = F + ab + 2 * (int)w->k[j].y * nb;
  }
  for (int o = 0; o < 3; o++) {
    w->lanes[o] = MLVQ_LANES(c0, o);
    w->lanes[3 + o] = MLVQ_LANES(c1, o);
  }
  for (int o = 0; o < 4; o++) {
    w->lanes[6 + o] = MLVQ_LANES(a0, o);
    w->lanes[10 + o] = MLVQ_LANES(a1, o);
  }
}

/* Level 4, the arithmetic → the raw RGB: four 2D functions at once in float4 lanes, since PoCL
 * runs scalar code as written; the same expressions per lane as one function at a time, summed
 * in the same order: the same values. */
__attribute__((always_inline)) inline float3 mlvq_walk_rgb(Stream I, Stream F, const MLVQWalk *w)
{
  const MLVQCell *c = &w->c;
  float wa0 = 1.0f - c->wa, wb0 = 1.0f - c->wb;
  const float4 *v = w->lanes;
  float4 sx = (float4)(w->s[0].x, w->s[1].x, w->s[2].x, w->s[3].x);
  float4 sz = (float4)(w->s[0].z, w->s[1].z, w->s[2].z, w->s[3].z);
  float4 p0m = v[0] * c->hw.x, p00 = v[1] * c->hw.y, p0p = v[2] * c->hw.z;
  float4 p1m = v[3] * c->hw.x, p10 = v[4] * c->hw.y, p1p = v[5] * c->hw.z;
  float4 lum = wa0 * sx * (p0m + p00 + p0p) + c->wa * sz * (p1m + p10 + p1p);
  float4 cb = wa0 * (v[6] * wb0 + v[8] * c->wb) + c->wa * (v[10] * wb0 + v[12] * c->wb);
  float4 cr = wa0 * (v[7] * wb0 + v[9] * c->wb) + c->wa * (v[11] * wb0 + v[13] * c->wb);
  float4 r, g, b;
#if !(defined(MLVQ_HDR) && !MLVQ_HDR) /* an LDR material's program: no LogLuv path */
  if (ITAB(H_HDR)) {
    float3 t0 = btf_logluv_to_rgb(lum.s0, cb.s0, cr.s0);
    float3 t1 = btf_logluv_to_rgb(lum.s1, cb.s1, cr.s1);
    float3 t2 = btf_logluv_to_rgb(lum.s2, cb.s2, cr.s2);
    float3 t3 = btf_logluv_to_rgb(lum.s3, cb.s3, cr.s3);
    r = (float4)(t0.x, t1.x, t2.x, t3.x);
    g = (float4)(t0.y, t1.y, t2.y, t3.y);
    b = (float4)(t0.z, t1.z, t2.z, t3.z);
  }
  else
#endif
  {
    r = BTF_VMAX(BTF_YCBCR_R(lum, cb, cr), (float4)(0.0f));
    g = BTF_VMAX(BTF_YCBCR_G(lum, cb, cr), (float4)(0.0f));
    b = BTF_VMAX(BTF_YCBCR_B(lum, cb, cr), (float4)(0.0f));
  }
  float3 rgb = (float3)(0.0f); /* summed function by function, in order */
  rgb += (float3)(r.s0, g.s0, b.s0) * w->scale.s0;
  rgb += (float3)(r.s1, g.s1, b.s1) * w->scale.s1;
  rgb += (float3)(r.s2, g.s2, b.s2) * w->scale.s2;
  rgb += (float3)(r.s3, g.s3, b.s3) * w->scale.s3;
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
  mlvq_walk_curves(F, &w);
  return mlvq_walk_rgb(I, F, &w);
}

/* Angles in degrees, theta <= 90, and wi the unit light direction of (theta_i, phi_i): the
 * original decoder's raw RGB (the light enters as wi only). */
inline float3 mlvq_decode(Stream I, Stream F, float2 uv, float3 wi, float theta_v, float phi_v)
{
  MLVQCell c = mlvq_cell(I, F, wi, theta_v, phi_v);
  return mlvq_texel(I, F, &c, uv);
}

/* --- dense -------------------------------------------------------------------------------- */

/* The two θ rings around ``theta`` (clamped to the measured range) → r0, r1 and the weight of
 * r1: the ring step of the dense and svd codecs' interpolation (core/grid.py). */
inline float ring_pair(Stream F, int theta_off, int n_rings, float theta, int *r0, int *r1)
{
  theta = BTF_CLAMPF(theta, FTAB(theta_off), FTAB(theta_off + n_rings - 1));
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

/* The four samples around azimuth ``phi`` on rings r0, r1 (ring_pair; wt the weight of r1):
 * their indices, weights and own azimuths (degrees). */
inline void ring_azimuth(Stream I, int offsets_off, int r0, int r1, float wt, float phi,
                         int idx[4], float w[4], float sample_phi[4])
{
  for (int k = 0; k < 2; k++) {
    int ring = k ? r1 : r0;
    float ring_w = k ? wt : 1.0f - wt;
    int start = ITAB(offsets_off + ring);
    int n = ITAB(offsets_off + ring + 1) - start;
    /* pos in [0, n] (btf_mod rounds up to 360 at most): i mod n by one conditional step, as
     * an integer division is some 40 cycles */
    float pos = btf_mod(phi, 360.0f) / (360.0f / n);
    float fl = BTF_FLOOR(pos);
    int s0 = btf_wrap((int)fl, n);
    float wp = pos - fl;
    int s1 = btf_wrap(s0 + 1, n);
    idx[2 * k] = start + s0;
    idx[2 * k + 1] = start + s1;
    w[2 * k] = ring_w * (1.0f - wp);
    w[2 * k + 1] = ring_w * wp;
    sample_phi[2 * k] = (float)s0 * 360.0f / (float)n;
    sample_phi[2 * k + 1] = (float)s1 * 360.0f / (float)n;
  }
}

inline void ring_weights(Stream I, Stream F, int theta_off, int offsets_off, int n_rings,
                         float theta, float phi, int idx[4], float w[4], float sample_phi[4])
{
  int r0, r1;
  float wt = ring_pair(F, theta_off, n_rings, theta, &r0, &r1);
  ring_azimuth(I, offsets_off, r0, r1, wt, phi, idx, w, sample_phi);
}

/* A dense decode's 16 (view, light) samples at one texel: where their RGB lies in F, their
 * weights, and the grazing-light factor. Computed first, read after (dense_sum): a random
 * query's 16 reads are cache misses, and issued together they overlap; eval_dense
 * (kernels/btf_eval.cl) computes a batch's taps before reading any. */
typedef struct {
  int base[16];
  float weight[16];
  float grazing;
} DenseTaps;

inline void dense_taps(Stream I, Stream F, float2 uv, float theta_i, float phi_i, float theta_v,
                       float phi_v, DenseTaps *t)
{
  int width = ITAB(H_WIDTH), height = ITAB(H_HEIGHT), n_lights = ITAB(H_N_LIGHTS);
  int x = btf_wrap((int)BTF_FLOOR(btf_mod(uv.x, 1.0f) * width), width);
  int y = btf_wrap((int)BTF_FLOOR(btf_mod(uv.y, 1.0f) * height), height);
  int vi[4], li[4];
  float vw[4], lw[4], view_phi[4], light_phi[4];
  int n_view_rings = ITAB(H_N_VIEW_RINGS), n_light_rings = ITAB(H_N_LIGHT_RINGS);
  ring_weights(I, F, ITAB(H_F_VIEW_THETA), ITAB(H_VIEW_OFFSETS), n_view_rings, theta_v, phi_v,
               vi, vw, view_phi);
  int texel = ITAB(H_F_DATA) + (y * width + x) * 3;
  int l0, l1; /* the light's rings: the same for the four view samples */
  float lt = ring_pair(F, ITAB(H_F_LIGHT_THETA), n_light_rings, theta_i, &l0, &l1);
  for (int a = 0; a < 4; a++) {
    ring_azimuth(I, ITAB(H_LIGHT_OFFSETS), l0, l1, lt, phi_i - phi_v + view_phi[a], li, lw,
                 light_phi);
    for (int b = 0; b < 4; b++) {
      /* a view sample of weight 0 (one ring, or the ring's weight exactly 0) adds nothing */
      t->weight[4 * a + b] = vw[a] > 0.0f ? vw[a] * lw[b] : 0.0f;
      t->base[4 * a + b] = texel + (vi[a] * n_lights + li[b]) * height * width * 3;
    }
  }
  float last = FTAB(ITAB(H_F_LIGHT_THETA) + n_light_rings - 1);
  t->grazing = theta_i > last ? cos(radians(theta_i)) / cos(radians(last)) : 1.0f;
}

inline float3 dense_sum(Stream F, const DenseTaps *t)
{
  float3 sum = (float3)(0.0f);
  for (int k = 0; k < 16; k++) {
    if (t->weight[k] > 0.0f) {
      int i = t->base[k];
      sum += t->weight[k] * (float3)(FTAB(i), FTAB(i + 1), FTAB(i + 2));
    }
  }
  return sum * t->grazing;
}

inline float3 dense_evaluate(Stream I, Stream F, float2 uv, float theta_i, float phi_i,
                             float theta_v, float phi_v)
{
  DenseTaps t;
  dense_taps(I, F, uv, theta_i, phi_i, theta_v, phi_v, &t);
  return dense_sum(F, &t);
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
    return mlvq_decode(I, F, uv, wi, theta_v, phi_v) * FTAB(F_VALUE_SCALE);
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
  /* CODEC_PRINCIPLED, as PrincipledBTF in btf_addon/core/codecs/analytic.py */
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

/* atan2(y, x) over the whole circle from the decode's polynomial atan (btf_angles.inc,
 * |error| < 1.1e-7 rad): PoCL's scalar atan2 was a tenth of a path-traced sample's time. */
inline float btf_atan2(float y, float x)
{
  float ay = fabs(y), ax = fabs(x);
  float hi = fmax(ay, ax), lo = fmin(ay, ax);
  float a = btf_atan_unit(hi > 0.0f ? lo / hi : 0.0f);
  a = ay > ax ? M_PI_2_F - a : a;
  a = signbit(x) ? M_PI_F - a : a; /* −0 too: atan2(±0, −0) = ±π */
  return copysign(a, y);
}

/* A direction's θ and φ in degrees, both through btf_atan2: PoCL's atan2 and acos were 8 % of a
 * demo sample (two directions per BTF evaluation). θ = atan2(|d.xy|, d.z) is as exact as
 * acos(d.z) away from the poles and more exact near them, and needs no unit length. */
inline float2 btf_theta_phi_deg(float3 d)
{
  float phi = degrees(btf_atan2(d.y, d.x));
  float theta = degrees(btf_atan2(sqrt(d.x * d.x + d.y * d.y), d.z));
  return (float2)(theta, phi < 0.0f ? phi + 360.0f : phi);
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
      walk[k].c = k ? walk[0].c : mlvq_cell(I, F, wi, view.x, view.y);
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
      mlvq_walk_curves(F, &walk[k]);
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
