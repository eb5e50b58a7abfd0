/* Directions for a path to continue in: the BTF's own importance sampling where its lobe is
 * known. Analytic GGX lobes (codecs ggx and principled) are sampled by their distribution of
 * visible normals (Heitz 2018, "Sampling the GGX Distribution of Visible Normals") mixed with
 * cosine sampling. Measured codecs (mlvq, dense, svd) packed with a sampling table
 * (btf_addon/core/sampling/btf_importance.py: H_F_IMPORTANCE ≠ 0) sample it: per view bin a piecewise-
 * constant density D on the concentric square (already mixed with the uniform square, i.e.
 * cosine sampling), pdf = D · cos θi / π; without a table, cosine sampling alone. The pdf of
 * the mixture is what MIS weighs the environment's samples against.
 *
 * Variant: HAS_BTF_IS (the table's code; by default where a measured codec is compiled in). */
#ifndef BTF_SAMPLING_H
#define BTF_SAMPLING_H

#include "btf_packed.h"

#ifndef HAS_BTF_IS
#define HAS_BTF_IS (HAS_MLVQ || HAS_DENSE || HAS_SVD)
#endif

/* Largest i < n with cdf[i] <= u (cdf[0] = 0, cdf[n] = 1): the one piecewise-constant CDF
 * search, for these tables and the environment's (render_direct.cl). */
inline int cdf_search(Stream cdf, int n, float u)
{
  int lo = 0, hi = n;
  while (hi - lo > 1) {
    int mid = (lo + hi) / 2;
    if (cdf[mid] <= u) {
      lo = mid;
    }
    else {
      hi = mid;
    }
  }
  return lo;
}

#if HAS_BTF_IS
/* Shirley and Chiu's concentric map [0,1]² → unit disk, and its inverse (as
 * core/sampling/btf_importance.py square_to_disk / disk_to_square). */
inline float2 is_square_to_disk(float2 s)
{
  float a = 2.0f * s.x - 1.0f, b = 2.0f * s.y - 1.0f;
  if (a == 0.0f && b == 0.0f) {
    return (float2)(0.0f);
  }
  float r, phi;
  if (fabs(a) > fabs(b)) {
    r = a;
    phi = (M_PI_F / 4.0f) * (b / a);
  }
  else {
    r = b;
    phi = M_PI_F / 2.0f - (M_PI_F / 4.0f) * (a / b);
  }
  return (float2)(r * cos(phi), r * sin(phi));
}

inline float2 is_disk_to_square(float2 d)
{
  /* atan2(y, x) with |y| ≤ x here is atan(y / x): the decode's polynomial (btf_angles.inc,
   * < 1.1e-7 rad), not PoCL's scalar atan2 (a tenth of a sample's time where it ran). */
  float r = sqrt(d.x * d.x + d.y * d.y), a, b;
  float ax = fabs(d.x), ay = fabs(d.y);
  if (ax > ay) {
    a = sign(d.x) * r;
    b = a * (4.0f / M_PI_F) * copysign(btf_atan_unit(ay / ax), d.y * sign(d.x));
  }
  else {
    b = sign(d.y) * r;
    a = b * (4.0f / M_PI_F) *
        copysign(btf_atan_unit(ay > 0.0f ? ax / ay : 0.0f), d.x * sign(d.y));
  }
  return clamp((float2)(a + 1.0f, b + 1.0f) * 0.5f, 0.0f, 1.0f);
}

/* The cell of the unit square a (normalised) direction falls in, on an n × n grid. */
inline int is_cell(float3 w, int n)
{
  float2 s = is_disk_to_square(w.xy * rsqrt(fmax(dot(w, w), 1e-30f)));
  int col = min((int)(s.x * n), n - 1), row = min((int)(s.y * n), n - 1);
  return row * n + col;
}

/* Float-stream offset of wo's view block (0: the material has no table). */
inline int is_view_block(Stream I, float3 wo)
{
  int base = ITAB(H_F_IMPORTANCE);
  if (base <= 0) {
    return 0;
  }
  int g = ITAB(H_IMPORTANCE_GRID), views = ITAB(H_IMPORTANCE_VIEWS);
  return base + is_cell(wo, views) * (2 * g * g + 2 * g + 1);
}

/* pdf (solid angle) of the table's wi; `block` from is_view_block. */
inline float is_pdf(Stream I, Stream F, int block, float3 wi)
{
  if (wi.z <= 0.0f) {
    return 0.0f;
  }
  int g = ITAB(H_IMPORTANCE_GRID);
  return F[block + is_cell(wi, g)] * wi.z * rsqrt(dot(wi, wi)) / M_PI_F;
}

/* A direction from the table: the row by the marginal CDF, the column by the row's CDF, then
 * uniform in the cell, through the concentric map and Malley's projection. */
inline float3 is_sample(Stream I, Stream F, int block, float2 u, int *cell)
{
  int g = ITAB(H_IMPORTANCE_GRID);
  Stream rows = F + block + g * g;
  int row = cdf_search(rows, g, u.x);
  float fr = (u.x - rows[row]) / fmax(rows[row + 1] - rows[row], 1e-30f);
  Stream cols = rows + (g + 1) * (1 + row);
  int col = cdf_search(cols, g, u.y);
  float fc = (u.y - cols[col]) / fmax(cols[col + 1] - cols[col], 1e-30f);
  /* kept inside the cell, so is_pdf finds the cell it was drawn from */
  float2 s = ((float2)(col, row) + clamp((float2)(fc, fr), 1e-4f, 1.0f - 1e-4f)) / (float)g;
  *cell = row * g + col;
  float2 d = is_square_to_disk(s);
  return (float3)(d.x, d.y, sqrt(fmax(1.0f - dot(d, d), 0.0f)));
}
#endif

/* Probability of drawing from the GGX lobe: 0 where the codec has none. A principled material
 * is a specular layer over a diffuse base: half its samples each, more as it gets metallic. */
inline float ggx_lobe_probability(Stream I, Stream F)
{
  int codec = ITAB(H_CODEC);
  if (codec == CODEC_GGX) {
    return 0.9f;
  }
  if (codec == CODEC_PRINCIPLED) {
    return 0.5f + 0.4f * FTAB(F_METALLIC);
  }
  return 0.0f;
}

/* pdf (solid angle) of reflecting wo into wi through a visible normal. */
inline float ggx_vndf_pdf(float alpha2, float3 wi, float3 wo)
{
  if (wi.z <= 0.0f || wo.z <= 0.0f) {
    return 0.0f;
  }
  float3 m = normalize(wi + wo);
  float g1 = 1.0f / (1.0f + ggx_lambda(alpha2, wo.z));
  return g1 * ggx_d(alpha2, m.z) / (4.0f * wo.z);
}

inline float3 ggx_vndf_sample(float alpha2, float3 wo, float2 u)
{
  float alpha = sqrt(alpha2);
  float3 vh = normalize((float3)(alpha * wo.x, alpha * wo.y, wo.z));
  float len2 = vh.x * vh.x + vh.y * vh.y;
  float3 t1 = len2 > 0.0f ? (float3)(-vh.y, vh.x, 0.0f) * rsqrt(len2) : (float3)(1.0f, 0.0f, 0.0f);
  float3 t2 = cross(vh, t1);
  float r = sqrt(u.x), phi = 2.0f * M_PI_F * u.y;
  float p1 = r * cos(phi), p2 = r * sin(phi);
  float s = 0.5f * (1.0f + vh.z);
  p2 = (1.0f - s) * sqrt(fmax(1.0f - p1 * p1, 0.0f)) + s * p2;
  float3 nh = p1 * t1 + p2 * t2 + sqrt(fmax(1.0f - p1 * p1 - p2 * p2, 0.0f)) * vh;
  float3 m = normalize((float3)(alpha * nh.x, alpha * nh.y, fmax(nh.z, 1e-6f)));
  return 2.0f * dot(wo, m) * m - wo;
}

/* The table's view block of wo for the functions below (0: no table; the analytic mixture).
 * A path vertex looks it up once for its environment sample's pdf and its BTF sample. */
inline int bsdf_table(Stream I, float3 wo)
{
#if HAS_BTF_IS
  return is_view_block(I, wo);
#else
  return 0;
#endif
}

/* The mixture's pdf of wi (tangent frame); `block` = bsdf_table(I, wo). */
inline float bsdf_pdf_at(Stream I, Stream F, int block, float3 wi, float3 wo)
{
#if HAS_BTF_IS
  if (block > 0) {
    return is_pdf(I, F, block, wi);
  }
#endif
  float cosine = fmax(wi.z, 0.0f) / M_PI_F;
  float p = ggx_lobe_probability(I, F);
  return p > 0.0f ? p * ggx_vndf_pdf(FTAB(F_ALPHA2), wi, wo) + (1.0f - p) * cosine : cosine;
}

/* A direction from the mixture and its pdf (*pdf = bsdf_pdf_at of it): `choice` in [0, 1)
 * picks the lobe, `u` places the sample. A table's sample knows its cell, so its pdf costs no
 * second lookup; the analytic mixture's is bsdf_pdf_at, as before the table existed. */
inline float3 bsdf_sample_at(Stream I, Stream F, int block, float3 wo, float choice, float2 u,
                             float *pdf)
{
#if HAS_BTF_IS
  if (block > 0) {
    int cell;
    float3 d = is_sample(I, F, block, u, &cell); /* the cosine share is inside the table */
    *pdf = F[block + cell] * d.z / M_PI_F;
    return d;
  }
#endif
  float3 d;
  float p = ggx_lobe_probability(I, F);
  if (choice < p) {
    d = ggx_vndf_sample(FTAB(F_ALPHA2), wo, u);
  }
  else {
    float r = sqrt(u.x), phi = 2.0f * M_PI_F * u.y;
    d = (float3)(r * cos(phi), r * sin(phi), sqrt(fmax(1.0f - u.x, 0.0f)));
  }
  *pdf = bsdf_pdf_at(I, F, block, d, wo);
  return d;
}

/* The same without a looked-up block. */
inline float bsdf_pdf(Stream I, Stream F, float3 wi, float3 wo)
{
  return bsdf_pdf_at(I, F, bsdf_table(I, wo), wi, wo);
}

inline float3 bsdf_sample(Stream I, Stream F, float3 wo, float choice, float2 u, float *pdf)
{
  return bsdf_sample_at(I, F, bsdf_table(I, wo), wo, choice, u, pdf);
}

#endif
