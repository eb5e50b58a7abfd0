/* BTF evaluation from the packed table layout shared with the GLSL back end
 * (btf_addon/core/packed.py writes it; shaders/btf_*_lib.glsl read the same layout). One material
 * is two streams: `I` (integers stored exactly as floats) and `F` (floats), each starting with a
 * header of sizes and table offsets. Reference for every step: btf_addon/core (numpy). */
#ifndef BTF_PACKED_H
#define BTF_PACKED_H

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

inline float btf_mod(float x, float m)
{
  return x - m * floor(x / m);
}

inline void btf_uniform_index(float x, float step, int max_index, int *i, float *w)
{
  int k = clamp((int)(x / step), 0, max_index);
  *i = k;
  *w = (x - k * step) / step;
}

/* --- MLVQ --------------------------------------------------------------------------------- */
/* Where the time goes (docs/accuracy.md "Decode throughput"): a decode is 4 (φ, θ) corners ×
 * 2 α nodes = 8 luminance curves and 8 colour curves, each behind a chain of 4–6 dependent
 * table reads, and the light angles. So the per-decode constants are computed once (the
 * Hermite step's three weights, the colour curves' two, every table offset), each curve is
 * one 3-float read, and the light's (β, α) comes from the direction vector with one sincos
 * instead of four trigonometric calls. Same arithmetic as btf_addon/core/mlvq.py up to float
 * rounding (tests/kernels/test_decode_speed.py states the tolerance). */

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
  if (i == 0) { /* m0 = p1 − p0 */
    return (float3)(0.0f, h00 - h10 - gm * h11, h01 + h10 + gm * h11);
  }
  return (float3)(-0.5f * h10, h00 - gm * h11, h01 + 0.5f * h10 + gm * h11);
}

typedef struct {
  int n_beta, n_alpha, n_theta, n_phi;
  int ib, ia, it, ip;
  float wa, wt, wp, wb;
  float3 hw; /* mlvq_hermite_weights(ib, wb) */
  /* table offsets, read once */
  int pdf2_col, pdf1, f2, fab;
} MLVQCell;

/* A curve s of the pdf1 table at the cell's β: one 3-float read (p[i−1] is read at i = 0 too,
 * with weight 0: the float stream's header precedes every table, so the read stays inside). */
inline float mlvq_curve(Stream F, const MLVQCell *c, int s)
{
  return dot(vload3(0, F + c->pdf1 + s * c->n_beta + c->ib - 1), c->hw);
}

/* One 2D function at (α, β) from its f_mlvq3 entry e = (scale, luminance fn, colour fn, 0):
 * luminance and colour, then YCbCr/LogLuv → RGB. */
inline float3 mlvq_pdf2(Stream I, Stream F, const MLVQCell *c, float4 e)
{
  int li = (int)e.y * c->n_alpha + c->ia;
  int ci = c->pdf2_col + (int)e.z * c->n_alpha + c->ia;
  float2 f0 = vload2(li, F + c->f2), f1 = vload2(li + 1, F + c->f2); /* (scale, curve) */
  float lum = (1.0f - c->wa) * f0.x * mlvq_curve(F, c, (int)f0.y) +
              c->wa * f1.x * mlvq_curve(F, c, (int)f1.y);
  /* (Cb, Cr) at the interval's two β nodes, one read per colour slice */
  float4 a0 = vload4(0, F + c->fab + 2 * (ITAB(ci) * c->n_beta + c->ib));
  float4 a1 = vload4(0, F + c->fab + 2 * (ITAB(ci + 1) * c->n_beta + c->ib));
  float2 cbcr = (1.0f - c->wa) * (a0.xy * (1.0f - c->wb) + a0.zw * c->wb) +
                c->wa * (a1.xy * (1.0f - c->wb) + a1.zw * c->wb);
  if (ITAB(H_HDR)) {
    return btf_logluv_to_rgb(lum, cbcr.x, cbcr.y);
  }
  return btf_ycbcr_to_rgb(lum, cbcr.x, cbcr.y);
}

/* Everything of a decode that does not depend on the texel: indices and weights of the
 * angles, table offsets. Angles in degrees, theta <= 90, and wi the unit light direction of
 * (theta_i, phi_i). A bilinear lookup computes it once for its four texels. */
inline MLVQCell mlvq_cell(Stream I, Stream F, float3 wi, float theta_i, float phi_i,
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
  float sin_pv = sincos(radians(phi_v), &cos_pv);
  float bx = sin_pv * wi.x - cos_pv * wi.y, by = -(cos_pv * wi.x + sin_pv * wi.y);
  bx = clamp(bx, -1.0f, 1.0f);

  /* (x, y, wi.z) is wi turned about the normal, a unit vector: cos β = √(y² + z²) without
   * the cancellation of √(1 − x²), and β, α as atan2 stay accurate at grazing light, where the
   * original's asin in float32 loses half the digits (β → ±90°). */
  float cos_beta = sqrt(by * by + wi.z * wi.z);
  float beta = degrees(atan2(bx, cos_beta));
  float alpha = cos_beta < 1e-3f ? 0.0f : degrees(atan2(by, fmax(wi.z, 0.0f)));
  alpha = clamp(alpha, -90.0f, 90.0f);

  if (ITAB(H_COS_BETA)) { /* samples uniform in sin β: the index straight from x = sin β */
    c.ib = clamp((int)((bx + 1.0f) * 0.5f * (c.n_beta - 1)), 0, c.n_beta - 2);
    float b0 = FTAB(ITAB(H_F_BETA) + c.ib), b1 = FTAB(ITAB(H_F_BETA) + c.ib + 1);
    c.wb = (beta - b0) / (b1 - b0);
  }
  else {
    btf_uniform_index(beta + 90.0f, 180.0f / (c.n_beta - 1), c.n_beta - 2, &c.ib, &c.wb);
  }
  btf_uniform_index(alpha + 90.0f, 180.0f / (c.n_alpha - 1), c.n_alpha - 2, &c.ia, &c.wa);
  btf_uniform_index(clamp(theta_v, 0.0f, 90.0f), 90.0f / (c.n_theta - 1), c.n_theta - 2, &c.it,
                    &c.wt);
  btf_uniform_index(clamp(view_phi, 0.0f, 360.0f), 360.0f / c.n_phi, c.n_phi - 1, &c.ip, &c.wp);
  c.hw = mlvq_hermite_weights(c.ib, c.wb, c.n_beta);
  c.pdf2_col = ITAB(H_PDF2_COLOURS);
  c.pdf1 = ITAB(H_F_PDF1);
  c.f2 = ITAB(H_F_MLVQ2);
  c.fab = ITAB(H_F_MLVQ_AB);
  return c;
}

/* The original decoder's raw RGB at the texel holding uv, for the cell's angles. */
inline float3 mlvq_texel(Stream I, Stream F, const MLVQCell *cp, float2 uv)
{
  MLVQCell c = *cp;
  int width = ITAB(H_WIDTH), height = ITAB(H_HEIGHT);
  int x = ((int)floor(btf_mod(uv.x, 1.0f) * width) - ITAB(H_COLS_OFFSET)) % width;
  int y = ((int)floor(btf_mod(uv.y, 1.0f) * height) - ITAB(H_ROWS_OFFSET)) % height;
  x = (x + width) % width;
  y = (y + height) % height;
  int texel = y * width + x;
  float2 t6 = vload2(texel, F + ITAB(H_F_MLVQ6)); /* (pdf6 scale, slot + 1) */
  int slot6 = (int)t6.y - 1;
  if (slot6 < 0) {
    return (float3)(0.0f);
  }
  int f4 = ITAB(H_F_MLVQ4), f3 = ITAB(H_F_MLVQ3);
  float3 rgb = (float3)(0.0f);
  for (int k = 0; k < 2; k++) {
    int phi = k ? (c.ip + 1) % c.n_phi : c.ip;
    float2 t4 = vload2(slot6 * c.n_phi + phi, F + f4); /* (pdf4 scale, pdf3 row) */
    float s4 = t4.x * (k ? c.wp : 1.0f - c.wp);
    int i3 = (int)t4.y * c.n_theta + c.it;
    float4 e0 = vload4(i3, F + f3), e1 = vload4(i3 + 1, F + f3);
    rgb += mlvq_pdf2(I, F, &c, e0) * (s4 * (e0.x * (1.0f - c.wt)));
    rgb += mlvq_pdf2(I, F, &c, e1) * (s4 * (e1.x * c.wt));
  }
  rgb *= t6.x;
  if (ITAB(H_HDR)) {
    rgb /= FTAB(F_HDR_VALUE);
  }
  return rgb;
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
  if (ITAB(H_CODEC) == CODEC_MLVQ) { /* the four texels share the angles' work */
    MLVQCell c = mlvq_cell(I, F, wi, light.x, light.y, view.x, view.y);
    for (int k = 0; k < 4; k++) {
      float x = (k & 1) ? x1 : x0, y = (k & 2) ? y1 : y0;
      float w = ((k & 1) ? f.x : 1.0f - f.x) * ((k & 2) ? f.y : 1.0f - f.y);
      float2 centre = (float2)((x + 0.5f) / size.x, (y + 0.5f) / size.y);
      sum += w * (mlvq_texel(I, F, &c, centre) * FTAB(F_VALUE_SCALE));
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
