/* Evaluate BTFs at lists of queries: one work-item per query.
 *
 * Queries arrive sanitised by the host (btf_addon/core/model.py): valid rows only, angles in
 * degrees with theta in [0, 90]. Each row of `q` is u, v, theta_i, phi_i, theta_v, phi_v;
 * directions wi, wo (unit, tangent frame) are passed alongside for the analytic codecs.
 *
 * Variants (-D): MLVQ_HDR (LogLuv instead of YCbCr), MLVQ_COS_BETA (beta samples uniform in
 * sin beta). */

#include "btf_mlvq.h"

#ifndef MLVQ_HDR
#define MLVQ_HDR 0
#endif
#ifndef MLVQ_COS_BETA
#define MLVQ_COS_BETA 1
#endif

__kernel void eval_mlvq(__global const float *q, const int n, const float value_scale,
                        __global float *out,
                        __global const float *pdf1, __global const float *ab_colors,
                        __global const int *index_ab, __global const int *pdf2_colours,
                        __global const int *pdf2_slices, __global const float *pdf2_scale,
                        __global const int *pdf2_indices, __global const int *pdf3_slices,
                        __global const float *pdf3_scale, __global const int *pdf4_slices,
                        __global const float *pdf4_scale, __global const int *pdf6_slices,
                        __global const float *pdf6_scale, __global const float *beta_angles,
                        const int4 counts,  /* n_beta, n_alpha, n_theta, n_phi */
                        const int4 spatial, /* width, height, rows_offset, cols_offset */
                        const float hdr_value)
{
  int gid = get_global_id(0);
  if (gid >= n) {
    return;
  }
  MLVQTables t = {pdf1, ab_colors, index_ab, pdf2_colours, pdf2_slices, pdf2_scale,
                  pdf2_indices, pdf3_slices, pdf3_scale, pdf4_slices, pdf4_scale,
                  pdf6_slices, pdf6_scale, beta_angles,
                  counts.x, counts.y, counts.z, counts.w,
                  spatial.x, spatial.y, spatial.z, spatial.w, hdr_value};
  __global const float *r = q + 6 * gid;
  float3 rgb = mlvq_decode(&t, r[0], r[1], r[2], r[3], r[4], r[5]) * value_scale;
  vstore3(rgb, gid, out);
}

__kernel void eval_lambertian(__global const float *wi, const int n, const float3 albedo,
                              __global float *out)
{
  int gid = get_global_id(0);
  if (gid >= n) {
    return;
  }
  float cos_i = fmax(wi[3 * gid + 2], 0.0f);
  vstore3(albedo * (cos_i / M_PI_F), gid, out);
}

/* GGX without Fresnel as Cycles' Glossy BSDF; value = D·G/(4 cos θo) (btf_addon/core/analytic.py). */
inline float ggx_lambda(float alpha2, float c)
{
  float c2 = fmax(c, 1e-6f);
  c2 *= c2;
  return 0.5f * (-1.0f + sqrt(1.0f + alpha2 * fmax(1.0f / c2 - 1.0f, 0.0f)));
}

__kernel void eval_ggx(__global const float *wi, __global const float *wo, const int n,
                       const float3 albedo, const float alpha2, __global float *out)
{
  int gid = get_global_id(0);
  if (gid >= n) {
    return;
  }
  float3 i = vload3(gid, wi), o = vload3(gid, wo);
  float3 h = i + o;
  float h_len = length(h);
  float cos_h = h_len > 1e-12f ? h.z / h_len : 0.0f;
  float denom = 1.0f + (alpha2 - 1.0f) * cos_h * cos_h;
  float d = alpha2 / (M_PI_F * denom * denom);
  float g = 1.0f / (1.0f + ggx_lambda(alpha2, i.z) + ggx_lambda(alpha2, o.z));
  float value = (i.z >= 0.0f && o.z >= 0.0f) ? d * g / (4.0f * fmax(o.z, 1e-6f)) : 0.0f;
  vstore3(albedo * value, gid, out);
}
