/* The light bake's lookup at a surface point (btf_addon/scene/bake_points.py documents the
 * rules; its numpy ``playback`` is the reference this code is tested against):
 *
 * - where: triangle t is cut into n² cells (tri_cuts[t]); its grid vertices (i, j), i + j ≤ n,
 *   at barycentrics (i/n, j/n) of corners 1 and 2, are bake points tri_points[tri_first[t] +
 *   k(i, j)], k(i, j) = i·(n + 1) − i·(i − 1)/2 + j; a point between them is the linear blend
 *   of its cell's three vertices;
 * - which view: V × V bins on the concentric square of the view direction in the surface's
 *   frame, bin (r, c) at index r·V + c on square point (centre(c), centre(r)), centre(k) =
 *   m + (1 − 2m)·k/(V − 1) with m = BAKE_BIN_MARGIN (bake_points.BIN_MARGIN, a define); a view
 *   between centres is the bilinear blend of the four nearest (clamped at the border);
 * - a point's row: V² + 1 float4, its bins then its light's direction (bake_points.pack_values),
 *   whose blend over the three vertices, normalised, is the lookup's light direction. */
#ifndef BTF_BAKE_H
#define BTF_BAKE_H

#ifndef BAKE_BIN_MARGIN_PERMILLE /* cl/renderer.py program_defines passes bake_points' */
#define BAKE_BIN_MARGIN_PERMILLE 20
#endif
#define BAKE_BIN_MARGIN ((float)BAKE_BIN_MARGIN_PERMILLE / 1000.0f)

/* The view direction's point on the concentric square (btf_importance.hemisphere_to_square):
 * Shirley and Chiu's inverse map of its projection on the disk. */
inline float2 bake_square(float3 w)
{
  /* grazing or below: just above the horizon, as bake_points.bin_weights */
  float xy = sqrt(w.x * w.x + w.y * w.y);
  w = (float3)(w.x, w.y, w.z > 0.0f ? w.z : 1e-6f * xy);
  w /= fmax(length(w), 1e-30f);
  float r = sqrt(w.x * w.x + w.y * w.y), a, b;
  if (fabs(w.x) > fabs(w.y)) {
    a = sign(w.x) * r;
    b = a * (4.0f / M_PI_F) * atan2(w.y * sign(w.x), fabs(w.x));
  }
  else {
    b = sign(w.y) * r;
    a = b * (4.0f / M_PI_F) * atan2(w.x * sign(w.y), fabs(w.y));
  }
  return clamp((float2)(a + 1.0f, b + 1.0f) * 0.5f, 0.0f, 1.0f);
}

/* A blend of unit light directions made one again; none (no light reached the points, or
 * directions that cancel): the normal, the direction a bake before them used. */
inline float3 bake_direction(float3 sum)
{
  float len = length(sum);
  return len > 1e-6f && isfinite(len) ? sum / len : (float3)(0.0f, 0.0f, 1.0f);
}

/* The bake's value (per channel) at triangle `tri`, barycentrics (bu, bv), for view `wo` in the
 * point's frame: 3 grid vertices × 4 view bins; `light_dir`: the vertices' light direction
 * blended (the frame's). `values`: V² + 1 float4 rows per point. */
inline float3 bake_lookup(__global const int *tri_cuts, __global const int *tri_first,
                          __global const int *tri_points, __global const float *values,
                          int view_bins, int tri, float bu, float bv, float3 wo,
                          float3 *light_dir)
{
  int n = max(tri_cuts[tri], 1);
  float a = bu * n, b = bv * n;
  if (!(isfinite(a) && isfinite(b))) {
    a = b = 0.0f;
  }
  int i = clamp((int)floor(a), 0, n - 1);
  int j = clamp((int)floor(b), 0, n - 1 - i);
  float fa = a - i, fb = b - j;
  int vi[3], vj[3];
  float w[3];
  /* the lower cell also where no upper one exists (past the far edge by rounding) */
  if (fa + fb <= 1.0f || i + j >= n - 1) {
    vi[0] = i, vj[0] = j, w[0] = 1.0f - fa - fb;
    vi[1] = i + 1, vj[1] = j, w[1] = fa;
    vi[2] = i, vj[2] = j + 1, w[2] = fb;
  }
  else {
    vi[0] = i + 1, vj[0] = j + 1, w[0] = fa + fb - 1.0f;
    vi[1] = i, vj[1] = j + 1, w[1] = 1.0f - fa;
    vi[2] = i + 1, vj[2] = j, w[2] = 1.0f - fb;
  }
  float total = 0.0f;
  for (int k = 0; k < 3; k++) {
    w[k] = fmax(w[k], 0.0f); /* outside the cell by rounding on its edges */
    total += w[k];
  }
  float2 s = (bake_square(wo) - BAKE_BIN_MARGIN) / (1.0f - 2.0f * BAKE_BIN_MARGIN) *
             (float)(view_bins - 1);
  s = clamp(s, 0.0f, (float)(view_bins - 1));
  int c0 = min((int)floor(s.x), max(view_bins - 2, 0));
  int r0 = min((int)floor(s.y), max(view_bins - 2, 0));
  float fx = s.x - c0, fy = s.y - r0;
  int c1 = min(c0 + 1, view_bins - 1), r1 = min(r0 + 1, view_bins - 1);
  int bins = view_bins * view_bins;
  float3 out = (float3)(0.0f), dir = (float3)(0.0f);
  for (int k = 0; k < 3; k++) {
    int point = tri_points[tri_first[tri] + vi[k] * (n + 1) - vi[k] * (vi[k] - 1) / 2 + vj[k]];
    __global const float *row = values + 4 * (bins + 1) * point;
    dir += w[k] * vload3(0, row + 4 * bins);
    float3 v = (vload3(0, row + 4 * (r0 * view_bins + c0)) * (1.0f - fx) +
                vload3(0, row + 4 * (r0 * view_bins + c1)) * fx) *
                   (1.0f - fy) +
               (vload3(0, row + 4 * (r1 * view_bins + c0)) * (1.0f - fx) +
                vload3(0, row + 4 * (r1 * view_bins + c1)) * fx) *
                   fy;
    out += w[k] * v;
  }
  *light_dir = bake_direction(dir);
  return total > 0.0f ? out / total : out;
}

/* Whether the bake's value at a material is per unit of its unshadowed light (analytic
 * materials: render_direct.cl bake_light traces that light beside F12's, and playback
 * multiplies the value by it converged per pixel, include/btf_lobe.h) rather than per unit
 * of bake_response. An analytic lobe's light changes with the view faster than view bins can
 * follow (docs/accuracy.md "The light bake played back"): what the bins carry is the ratio,
 * shadows and interreflection, which changes slowly. */
inline bool bake_over_unshadowed(__global const float *I)
{
  int codec = ITAB(H_CODEC);
  return !(codec == CODEC_MLVQ || codec == CODEC_DENSE || codec == CODEC_SVD);
}

/* What a measured material's bake value is per unit of: its response at the point's texel
 * (its detail, which playback decodes live), times exposure, to one light from `light_dir`,
 * the bake's mean direction of the light the point receives (in sp's frame, bake_lookup's).
 * The texels' pattern is then the one the point's main light draws: a woven ground under a
 * World whose light comes 29° off the zenith was 3.0 % off F12 with a light along the normal,
 * 1.9 % with that mean (docs/accuracy.md "The light bake played back"). */
inline float3 bake_response(__global const float *I, __global const float *F,
                            const SurfacePoint *sp, float3 light_dir)
{
  return btf_mapped(I, F, sp, light_dir) * sp->exposure;
}

#endif
