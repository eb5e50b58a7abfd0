/* Evaluate a BTF at lists of queries: one work-item per query (btf_addon/cl/evaluate.py).
 *
 * Queries arrive sanitised by the host (btf_addon/core/model.py): valid rows only. Each row of
 * `q` is u, v, theta_i, phi_i, theta_v, phi_v (degrees, theta in [0, 90]); `dirs` holds the
 * matching unit wi, wo (tangent frame) for the analytic codecs. Tables: the packed layout of
 * btf_addon/core/codecs/packed.py, shared with the GLSL back end. */

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

#if MLVQ_BATCH == 8
/* The batch's angles in float8 (btf_angles.inc a second time): PoCL runs a work-item's code as
 * scalar instructions, so the eight cells' arithmetic is written as vector arithmetic. */
#define BTF_TMAX(a, b) BTF_VMAX((a), (float8)(b))
#define BTF_TMIN(a, b) BTF_VMIN((a), (float8)(b))
#define BTF_TABS(x) as_float8(as_uint8(x) & 0x7fffffffu)
#ifdef __clang__ /* PoCL's convert_int8 is a call */
#define BTF_TOINT(x) __builtin_convertvector((x), int8)
#define BTF_TOFLOAT(i) __builtin_convertvector((i), float8)
#else
#define BTF_TOINT(x) convert_int8(x)
#define BTF_TOFLOAT(i) convert_float8(i)
#endif
/* lane by lane with the scalar builtins (single instructions under clang) */
#define BTF_LANES(f, x) \
  ((float8)(f((x).s0), f((x).s1), f((x).s2), f((x).s3), f((x).s4), f((x).s5), f((x).s6), \
            f((x).s7)))
#define BTF_TSQRT(x) BTF_LANES(BTF_SQRT, x)
#define BTF_TRINT(x) BTF_LANES(BTF_RINT, x)
#define BTF_TFLOOR(x) BTF_LANES(BTF_FLOOR, x)
#define BTF_TCOPYSIGN(a, b) \
  as_float8((as_uint8(a) & 0x7fffffffu) | (as_uint8(b) & 0x80000000u))
#define BTF_TLOAD(p, i) \
  ((float8)((p)[(i).s0], (p)[(i).s1], (p)[(i).s2], (p)[(i).s3], (p)[(i).s4], (p)[(i).s5], \
            (p)[(i).s6], (p)[(i).s7]))
#define BTF_T float8
#define BTF_I int8
#define BTF_N(name) name##8
#include "btf_angles.inc"

typedef union {
  float8 v;
  float s[8];
} Lanes8;
typedef union {
  int8 v;
  int s[8];
} IntLanes8;
#endif

__kernel void eval_mlvq(__global const float *q, __global const float *dirs, const int n,
                        __global const float *I, __global const float *F, __global float *out)
{
  int first = get_global_id(0) * MLVQ_BATCH;
  MLVQWalk w[MLVQ_BATCH];
#if MLVQ_BATCH == 8
  Lanes8 wx, wy, wz, tv, pv;
  for (int j = 0; j < 8; j++) {
    int row = BTF_IMIN(first + j, n - 1); /* a short last batch repeats its last row */
    wx.s[j] = dirs[6 * row];
    wy.s[j] = dirs[6 * row + 1];
    wz.s[j] = dirs[6 * row + 2];
    tv.s[j] = q[6 * row + 4];
    pv.s[j] = q[6 * row + 5];
  }
  MLVQAngles8 a8 = mlvq_angles8(I, F, wx.v, wy.v, wz.v, tv.v, pv.v);
  IntLanes8 ib = {a8.ib}, ia = {a8.ia}, it = {a8.it}, ip = {a8.ip}, ip1 = {a8.ip1};
  Lanes8 wb = {a8.wb}, wa = {a8.wa}, wt = {a8.wt}, wp = {a8.wp};
  Lanes8 hm = {a8.hm}, h0 = {a8.h0}, hp = {a8.hp};
  for (int j = 0; j < 8; j++) {
    MLVQAngles a = {ib.s[j], ia.s[j], it.s[j], ip.s[j], ip1.s[j], wb.s[j], wa.s[j],
                    wt.s[j], wp.s[j], hm.s[j], h0.s[j], hp.s[j]};
    w[j].c = mlvq_cell_of(I, a);
    int row = BTF_IMIN(first + j, n - 1);
    mlvq_walk_texel(I, F, &w[j], btf_ld2(q + 6 * row));
  }
#else
  for (int j = 0; j < MLVQ_BATCH; j++) {
    int row = BTF_IMIN(first + j, n - 1); /* a short last batch repeats its last row */
    __global const float *r = q + 6 * row;
    w[j].c = mlvq_cell(I, F, btf_ld3(dirs + 6 * row), r[4], r[5]);
    mlvq_walk_texel(I, F, &w[j], btf_ld2(r));
  }
#endif
  for (int j = 0; j < MLVQ_BATCH; j++) {
    mlvq_walk_rows(F, &w[j]);
  }
  for (int j = 0; j < MLVQ_BATCH; j++) {
    mlvq_walk_functions(I, F, &w[j]);
  }
  for (int j = 0; j < MLVQ_BATCH; j++) {
    mlvq_walk_curves(F, &w[j]);
  }
  float scale = FTAB(F_VALUE_SCALE);
  for (int j = 0; j < MLVQ_BATCH; j++) {
    float3 value = mlvq_walk_rgb(I, F, &w[j]) * scale;
    if (first + j < n) {
      btf_st3(out, first + j, value);
    }
  }
}

/* eval_btf for a dense material, DENSE_BATCH queries per work-item: every query's taps
 * (btf_packed.h dense_taps) before any read, so the misses of the batch's 16·B reads overlap;
 * the same values as eval_btf. */
#ifndef DENSE_BATCH
#define DENSE_BATCH 1
#endif
__kernel void eval_dense(__global const float *q, __global const float *dirs, const int n,
                         __global const float *I, __global const float *F, __global float *out)
{
  int first = get_global_id(0) * DENSE_BATCH;
  DenseTaps t[DENSE_BATCH];
  for (int j = 0; j < DENSE_BATCH; j++) {
    __global const float *r = q + 6 * BTF_IMIN(first + j, n - 1);
    dense_taps(I, F, btf_ld2(r), r[2], r[3], r[4], r[5], &t[j]);
  }
  for (int j = 0; j < DENSE_BATCH; j++) {
    float3 value = dense_sum(F, &t[j]);
    if (first + j < n) {
      btf_st3(out, first + j, value);
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
