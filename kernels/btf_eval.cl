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
