/* Evaluate a BTF at lists of queries: one work-item per query (btf_addon/cl/evaluate.py).
 *
 * Queries arrive sanitised by the host (btf_addon/core/model.py): valid rows only. Each row of
 * `q` is u, v, theta_i, phi_i, theta_v, phi_v (degrees, theta in [0, 90]); `dirs` holds the
 * matching unit wi, wo (tangent frame) for the analytic codecs. Tables: the packed layout of
 * btf_addon/core/packed.py, shared with the GLSL back end. */

#include "btf_packed.h"

__kernel void eval_btf(__global const float *q, __global const float *dirs, const int n,
                       __global const float *I, __global const float *F, __global float *out)
{
  int gid = get_global_id(0);
  if (gid >= n) {
    return;
  }
  __global const float *r = q + 6 * gid;
  float3 wi = vload3(2 * gid, dirs), wo = vload3(2 * gid + 1, dirs);
  float3 value = btf_evaluate(I, F, (float2)(r[0], r[1]), wi, wo, r[2], r[3], r[4], r[5]);
  vstore3(value, gid, out);
}

/* eval_btf for an MLVQ material, MLVQ_BATCH queries per work-item (rows gid·B … gid·B + B − 1):
 * each level of the table walk (btf_packed.h MLVQWalk) runs for the whole batch before the
 * next, so the cache misses of B decodes overlap; the same values as eval_btf. */
#ifndef MLVQ_BATCH
#define MLVQ_BATCH 1
#endif
__kernel void eval_mlvq(__global const float *q, __global const float *dirs, const int n,
                        __global const float *I, __global const float *F, __global float *out)
{
  int first = get_global_id(0) * MLVQ_BATCH;
  MLVQWalk w[MLVQ_BATCH];
  for (int j = 0; j < MLVQ_BATCH; j++) {
    int row = BTF_IMIN(first + j, n - 1); /* a short last batch repeats its last row */
    __global const float *r = q + 6 * row;
    w[j].c = mlvq_cell(I, F, btf_ld3(dirs + 6 * row), r[2], r[3], r[4], r[5]);
    mlvq_walk_texel(I, F, &w[j], btf_ld2(r));
  }
  for (int j = 0; j < MLVQ_BATCH; j++) {
    mlvq_walk_rows(F, &w[j]);
  }
  for (int j = 0; j < MLVQ_BATCH; j++) {
    mlvq_walk_functions(I, F, &w[j]);
  }
  float scale = FTAB(F_VALUE_SCALE);
  for (int j = 0; j < MLVQ_BATCH; j++) {
    float3 value = mlvq_walk_rgb(I, F, &w[j]) * scale;
    if (first + j < n) { /* plain stores: PoCL's vstore3 is a call too */
      out[3 * (first + j)] = value.x;
      out[3 * (first + j) + 1] = value.y;
      out[3 * (first + j) + 2] = value.z;
    }
  }
}

/* The bilinear filtered lookup (btf_filtered, FILTER_LINEAR: four decodes) at the same rows:
 * what benchmarks/bench_decode.py times as "filtered lookups". */
__kernel void eval_btf_filtered(__global const float *q, __global const float *dirs,
                                const int n, __global const float *I, __global const float *F,
                                __global float *out)
{
  int gid = get_global_id(0);
  if (gid >= n) {
    return;
  }
  float3 wi = vload3(2 * gid, dirs), wo = vload3(2 * gid + 1, dirs);
  vstore3(btf_filtered(I, F, FILTER_LINEAR, vload2(0, q + 6 * gid), wi, wo), gid, out);
}

/* The mapped lookup a renderer does at surface points (btf_addon/core/mapping.py
 * mapped_evaluate, the reference): per point 20 floats — world position, unit shading normal,
 * the mesh's tangent frame t and b, mesh uv, light and view directions (world, unit) — and
 * one material block (MATERIAL_BLOCK_FLOATS floats). Exposure is not applied. */
#include "btf_trace.h"
#include "btf_surface.h"

__kernel void eval_mapped(__global const float *points, __global const float *block, const int n,
                          __global const float *I, __global const float *F, __global float *out)
{
  int gid = get_global_id(0);
  if (gid >= n) {
    return;
  }
  __global const float *r = points + 20 * gid;
  SurfacePoint sp;
  sp.p = vload3(0, r);
  sp.n = vload3(0, r + 3);
  sp.t = vload3(0, r + 6);
  sp.b = vload3(0, r + 9);
  sp.uv = vload2(0, r + 12);
  float3 wi_world = vload3(0, r + 14), wo_world = vload3(0, r + 17);
  sp.wo = (float3)(dot(wo_world, sp.t), dot(wo_world, sp.b), dot(wo_world, sp.n));
  float3 wi = (float3)(dot(wi_world, sp.t), dot(wi_world, sp.b), dot(wi_world, sp.n));
  map_point(&sp, block);
  float3 value = (wi.z > 0.0f && sp.wo.z > 0.0f) ? btf_mapped(I, F, &sp, wi) : (float3)(0.0f);
  vstore3(value, gid, out);
}
