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

inline float mlvq_pdf1(Stream I, Stream F, int s, int i, float w, int n_beta)
{
  int row = ITAB(H_F_PDF1) + s * n_beta;
  float p0 = FTAB(row + i), p1 = FTAB(row + i + 1);
  float m0 = (i == 0) ? p1 - p0 : 0.5f * (p1 - FTAB(row + i - 1));
  float m1 = (i == n_beta - 2) ? p1 - p0 : 0.5f * (p1 - p0);
  float t2 = w * w, t3 = t2 * w;
  float h01 = -2.0f * t3 + 3.0f * t2;
  float h00 = 1.0f - h01;
  float h11 = t3 - t2;
  float h10 = h11 - t2 + w;
  return h00 * p0 + h10 * m0 + h01 * p1 + h11 * m1;
}

inline float2 mlvq_ab(Stream I, Stream F, int c, int i, float w, int n_beta)
{
  int row = ITAB(H_INDEX_AB) + c * n_beta;
  int ab = ITAB(H_F_AB_COLORS);
  int a = ITAB(row + i), b = ITAB(row + i + 1);
  float2 ca = (float2)(FTAB(ab + 2 * a), FTAB(ab + 2 * a + 1));
  float2 cb = (float2)(FTAB(ab + 2 * b), FTAB(ab + 2 * b + 1));
  return ca * (1.0f - w) + cb * w;
}

inline float3 mlvq_pdf2(Stream I, Stream F, int idx2, int ia, float wa, int ib, float wb,
                        int n_beta, int n_alpha)
{
  int lum_fn = ITAB(ITAB(H_PDF2_INDICES) + 2 * idx2);
  int col_fn = ITAB(ITAB(H_PDF2_INDICES) + 2 * idx2 + 1);
  float lum = 0.0f;
  float2 cbcr = (float2)(0.0f);
  for (int k = 0; k < 2; k++) {
    int a = ia + k;
    float w = k ? wa : 1.0f - wa;
    int li = lum_fn * n_alpha + a;
    lum += w * FTAB(ITAB(H_F_PDF2_SCALE) + li) *
           mlvq_pdf1(I, F, ITAB(ITAB(H_PDF2_SLICES) + li), ib, wb, n_beta);
    cbcr += w * mlvq_ab(I, F, ITAB(ITAB(H_PDF2_COLOURS) + col_fn * n_alpha + a), ib, wb, n_beta);
  }
  if (ITAB(H_HDR)) {
    return btf_logluv_to_rgb(lum, cbcr.x, cbcr.y);
  }
  return btf_ycbcr_to_rgb(lum, cbcr.x, cbcr.y);
}

/* Angles in degrees, theta <= 90: the original decoder's raw RGB. */
inline float3 mlvq_decode(Stream I, Stream F, float2 uv, float theta_i, float phi_i,
                          float theta_v, float phi_v)
{
  int n_beta = ITAB(H_N_BETA), n_alpha = ITAB(H_N_ALPHA);
  int n_theta = ITAB(H_N_THETA), n_phi = ITAB(H_N_PHI);
  int width = ITAB(H_WIDTH), height = ITAB(H_HEIGHT);
  int x = ((int)floor(btf_mod(uv.x, 1.0f) * width) - ITAB(H_COLS_OFFSET)) % width;
  int y = ((int)floor(btf_mod(uv.y, 1.0f) * height) - ITAB(H_ROWS_OFFSET)) % height;
  x = (x + width) % width;
  y = (y + height) % height;

  float view_phi = btf_mod(360.0f - phi_v, 360.0f);
  float light_phi = btf_mod((360.0f - phi_i) - (90.0f + view_phi), 360.0f);
  float th = radians(theta_i), ph = radians(light_phi);
  float bx = cos(ph) * sin(th), by = sin(ph) * sin(th);
  float beta = asin(clamp(bx, -1.0f, 1.0f));
  float cos_beta = cos(beta);
  float alpha = cos_beta < 1e-3f ? 0.0f : asin(clamp(by / cos_beta, -1.0f, 1.0f));
  beta = clamp(degrees(beta), -90.0f, 90.0f);
  alpha = clamp(degrees(alpha), -90.0f, 90.0f);

  int ib, ia, it, ip;
  float wb, wa, wt, wp;
  if (ITAB(H_COS_BETA)) {
    ib = clamp((int)((sin(radians(beta)) + 1.0f) * 0.5f * (n_beta - 1)), 0, n_beta - 2);
    float b0 = FTAB(ITAB(H_F_BETA) + ib), b1 = FTAB(ITAB(H_F_BETA) + ib + 1);
    wb = (beta - b0) / (b1 - b0);
  }
  else {
    btf_uniform_index(beta + 90.0f, 180.0f / (n_beta - 1), n_beta - 2, &ib, &wb);
  }
  btf_uniform_index(alpha + 90.0f, 180.0f / (n_alpha - 1), n_alpha - 2, &ia, &wa);
  btf_uniform_index(clamp(theta_v, 0.0f, 90.0f), 90.0f / (n_theta - 1), n_theta - 2, &it, &wt);
  btf_uniform_index(clamp(view_phi, 0.0f, 360.0f), 360.0f / n_phi, n_phi - 1, &ip, &wp);

  int texel = y * width + x;
  int slot6 = ITAB(ITAB(H_PDF6_SLICES) + texel) - 1;
  if (slot6 < 0) {
    return (float3)(0.0f);
  }
  float3 rgb = (float3)(0.0f);
  for (int k = 0; k < 2; k++) {
    int phi = k ? (ip + 1) % n_phi : ip;
    int i4 = slot6 * n_phi + phi;
    int idx3 = ITAB(ITAB(H_PDF4_SLICES) + i4);
    float s4 = FTAB(ITAB(H_F_PDF4_SCALE) + i4) * (k ? wp : 1.0f - wp);
    for (int j = 0; j < 2; j++) {
      int i3 = idx3 * n_theta + it + j;
      float s3 = FTAB(ITAB(H_F_PDF3_SCALE) + i3) * (j ? wt : 1.0f - wt);
      rgb += mlvq_pdf2(I, F, ITAB(ITAB(H_PDF3_SLICES) + i3), ia, wa, ib, wb, n_beta, n_alpha) *
             (s4 * s3);
    }
  }
  rgb *= FTAB(ITAB(H_F_PDF6_SCALE) + texel);
  if (ITAB(H_HDR)) {
    rgb /= FTAB(F_HDR_VALUE);
  }
  return rgb;
}

/* --- dense -------------------------------------------------------------------------------- */

inline void ring_weights(Stream I, Stream F, int theta_off, int offsets_off, int n_rings,
                         float theta, float phi, int idx[4], float w[4])
{
  float first = FTAB(theta_off), last = FTAB(theta_off + n_rings - 1);
  theta = clamp(theta, first, last);
  int r0 = 0;
  for (int r = 1; r < n_rings - 1; r++) {
    if (FTAB(theta_off + r) <= theta) {
      r0 = r;
    }
  }
  float wt = 0.0f;
  int r1 = r0;
  if (n_rings > 1) {
    r1 = r0 + 1;
    wt = (theta - FTAB(theta_off + r0)) / (FTAB(theta_off + r1) - FTAB(theta_off + r0));
  }
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
  if (codec == CODEC_MLVQ) {
    return mlvq_decode(I, F, uv, theta_i, phi_i, theta_v, phi_v) * FTAB(F_VALUE_SCALE);
  }
  if (codec == CODEC_DENSE) {
    return dense_evaluate(I, F, uv, theta_i, phi_i, theta_v, phi_v);
  }
  if (codec == CODEC_SVD) {
    return svd_evaluate(I, F, uv, theta_i, phi_i, theta_v, phi_v) * FTAB(F_VALUE_SCALE);
  }
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
  for (int k = 0; k < 4; k++) {
    float x = (k & 1) ? x1 : x0, y = (k & 2) ? y1 : y0;
    float w = ((k & 1) ? f.x : 1.0f - f.x) * ((k & 2) ? f.y : 1.0f - f.y);
    float2 centre = (float2)((x + 0.5f) / size.x, (y + 0.5f) / size.y);
    sum += w * btf_evaluate(I, F, centre, wi, wo, light.x, light.y, view.x, view.y);
  }
  return sum;
}

#endif
