/* Final render, deterministic direct-lighting mode: camera rays, the nearest surface, and exactly
 * the given virtual lights (no MIS, no bounces) — the common ground with the GLSL viewport.
 *
 * Variants: HAS_SHADOWS (shadow rays towards every light; off when the scene analysis proves no
 * surface can shadow another, btf_addon/render/analysis.py).
 *
 * Passes written per pixel: combined (RGBA), depth (distance along the camera axis from the
 * camera, camera_forward.w = −dot(camera position, forward); 1e10 where
 * nothing is hit, as Blender), normal (world-space shading normal), uv (mesh UV). Rows
 * [row0, row0 + rows) are rendered, so the host can show progress and stop between bands. */

#include "btf_packed.h"
#include "btf_trace.h"

#ifndef HAS_SHADOWS
#define HAS_SHADOWS 1
#endif

inline float3 env_lookup(__global const float *env, int w, int h, float2 params, float3 d)
{
  /* As shaders/env_lib.glsl: Blender's orientation, bilinear, wrapping in u. */
  float c = cos(params.x), s = sin(params.x);
  float3 m = normalize((float3)(c * d.x - s * d.y, s * d.x + c * d.y, d.z));
  float u = (M_PI_F - atan2(m.y, m.x)) / (2.0f * M_PI_F);
  float v = acos(clamp(m.z, -1.0f, 1.0f)) / M_PI_F;
  float fx = u * w - 0.5f, fy = clamp(v * h - 0.5f, 0.0f, (float)(h - 1));
  int x0 = (int)floor(fx), y0 = (int)floor(fy);
  float ax = fx - x0, ay = fy - y0;
  int x1 = x0 + 1, y1 = min(y0 + 1, h - 1);
  x0 = ((x0 % w) + w) % w;
  x1 = ((x1 % w) + w) % w;
  float3 c00 = vload3(0, env + 4 * (y0 * w + x0)), c10 = vload3(0, env + 4 * (y0 * w + x1));
  float3 c01 = vload3(0, env + 4 * (y1 * w + x0)), c11 = vload3(0, env + 4 * (y1 * w + x1));
  return ((c00 * (1 - ax) + c10 * ax) * (1 - ay) + (c01 * (1 - ax) + c11 * ax) * ay) * params.y;
}

__kernel void render_direct(const int width, const int height, const int row0,
                            __global const float *world_from_clip, const float4 camera_forward,
                            const int tri_count, __global const float *bounds,
                            __global const int *links,
                            __global const float *corners, __global const int *tri_material,
                            __global const float *ints, __global const float *floats,
                            __global const int *material_offsets,
                            __global const float *material_params, __global const float *lights,
                            const int n_lights, const float eps, __global const float *env,
                            const int env_w, const int env_h, const float2 env_params,
                            __global float *combined, __global float *depth,
                            __global float *normal_out, __global float *uv_out)
{
  int x = get_global_id(0), yr = get_global_id(1);
  int y = row0 + yr;
  if (x >= width || y >= height) {
    return;
  }
  int px = yr * width + x; /* index inside this band's buffers */
  float2 ndc = (float2)((x + 0.5f) / width * 2.0f - 1.0f, 1.0f - (y + 0.5f) / height * 2.0f);
  float4 m0 = vload4(0, world_from_clip), m1 = vload4(1, world_from_clip);
  float4 m2 = vload4(2, world_from_clip), m3 = vload4(3, world_from_clip); /* rows */
  float4 pn = (float4)(ndc, -1.0f, 1.0f), pf = (float4)(ndc, 1.0f, 1.0f);
  float4 near = (float4)(dot(m0, pn), dot(m1, pn), dot(m2, pn), dot(m3, pn));
  float4 far = (float4)(dot(m0, pf), dot(m1, pf), dot(m2, pf), dot(m3, pf));
  float3 o = near.xyz / near.w;
  float3 d = normalize(far.xyz / far.w - o);

  float t = 0.0f, bu = 0.0f, bv = 0.0f;
  int tri = tri_count > 0 ? trace(o, d, 0.0f, INFINITY, bounds, links, corners, false, &t, &bu, &bv)
                          : -1;
  if (tri < 0) {
    vstore4((float4)(env_lookup(env, env_w, env_h, env_params, d), 1.0f), px, combined);
    depth[px] = 1e10f;
    vstore3((float3)(0.0f), px, normal_out);
    vstore2((float2)(0.0f), px, uv_out);
    return;
  }
  __global const float *c = corners + 36 * tri;
  float w0 = 1.0f - bu - bv;
  float3 p = o + t * d;
  /* Shadow rays start from the point lifted onto the surface that the smooth normals describe
   * (Hanika 2021, "Hacking the shadow terminator"): on tessellated smooth meshes this stops
   * faces from shadowing their neighbours near the terminator. */
  float3 lifted = (float3)(0.0f);
  for (int k = 0; k < 3; k++) {
    float3 pk = vload3(0, c + 12 * k), nk = normalize(vload3(0, c + 12 * k + 3));
    float3 tmp = p - pk;
    tmp -= fmin(dot(tmp, nk), 0.0f) * nk;
    lifted += (k == 0 ? w0 : (k == 1 ? bu : bv)) * (pk + tmp);
  }
  /* Corner k at c + 12k: position [0, 3), normal [3, 6), uv [6, 8), tangent + sign [8, 12). */
  float3 n = normalize(w0 * vload3(0, c + 3) + bu * vload3(0, c + 15) + bv * vload3(0, c + 27));
  float2 uv = w0 * vload2(0, c + 6) + bu * vload2(0, c + 18) + bv * vload2(0, c + 30);
  float4 tg = w0 * vload4(0, c + 8) + bu * vload4(0, c + 20) + bv * vload4(0, c + 32);
  float3 wo_world = -d;
  float side = dot(n, wo_world) < 0.0f ? -1.0f : 1.0f; /* back faces shaded as seen */
  n *= side;
  float3 tt = tg.xyz - n * dot(n, tg.xyz);
  float tl = length(tt);
  tt = tl > 1e-8f ? tt / tl
                  : normalize(cross(fabs(n.z) < 0.9f ? (float3)(0, 0, 1) : (float3)(1, 0, 0), n));
  float3 b = cross(n, tt) * (c[11] < 0.0f ? -1.0f : 1.0f) * side;
  float3 wo = (float3)(dot(wo_world, tt), dot(wo_world, b), dot(wo_world, n));
  float2 view = btf_theta_phi_deg(wo);

  int mat = tri_material[tri];
  __global const float *I = ints + material_offsets[2 * mat];
  __global const float *F = floats + material_offsets[2 * mat + 1];
  __global const float *mp = material_params + 8 * mat;
  float2 buv = (float2)(mp[0] * uv.x + mp[2] * uv.y, mp[1] * uv.x + mp[3] * uv.y);
  float3 sum = (float3)(0.0f);
  if (wo.z > 0.0f) {
    for (int i = 0; i < n_lights; i++) {
      float3 dir = vload3(0, lights + 8 * i);
      float3 wi = (float3)(dot(dir, tt), dot(dir, b), dot(dir, n));
      if (wi.z <= 0.0f) {
        continue;
      }
#if HAS_SHADOWS
      float ts, us, vs;
      float3 start = (side > 0.0f ? lifted : p) + n * eps; /* lifting assumes the outer side */
      if (trace(start, dir, eps, INFINITY, bounds, links, corners, true, &ts, &us, &vs) >= 0) {
        continue;
      }
#endif
      float2 light = btf_theta_phi_deg(wi);
      sum += btf_evaluate(I, F, buv, wi, wo, light.x, light.y, view.x, view.y) *
             vload3(0, lights + 8 * i + 4);
    }
  }
  sum *= mp[4] / (float)max(n_lights, 1);
  vstore4((float4)(sum, 1.0f), px, combined);
  depth[px] = dot(p, camera_forward.xyz) + camera_forward.w; /* distance along the camera axis */
  vstore3(n, px, normal_out);
  vstore2(uv, px, uv_out);
}

/* --- Monte Carlo environment lighting with MIS ----------------------------------------------
 * The same camera rays and shading frame as render_direct, but the World is sampled
 * continuously: per sample one light direction drawn from the environment's piecewise-constant
 * distribution (btf_addon/core/envmap.py, same tables) and one cosine-weighted direction, combined
 * with the power heuristic. Unbiased for any BTF; converges to the integral the virtual lights
 * approximate. Seeds differ per pass so the host can average passes progressively. */

inline uint pcg_hash(uint v)
{
  uint state = v * 747796405u + 2891336453u;
  uint word = ((state >> ((state >> 28u) + 4u)) ^ state) * 277803737u;
  return (word >> 22u) ^ word;
}

inline float rand01(uint *state)
{
  *state = pcg_hash(*state);
  return (float)(*state >> 8) * (1.0f / 16777216.0f);
}

/* Largest index i in [0, n) with cdf[i] <= u (cdf has n + 1 entries from 0 to 1). */
inline int cdf_search(__global const float *cdf, int n, float u)
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

inline float3 env_direction(float s, float t, float rotation)
{
  float theta = M_PI_F * t, phi = M_PI_F - 2.0f * M_PI_F * s;
  float3 m = (float3)(sin(theta) * cos(phi), sin(theta) * sin(phi), cos(theta));
  float c = cos(rotation), sn = sin(rotation); /* world = R(-rotation) · map */
  return (float3)(c * m.x + sn * m.y, -sn * m.x + c * m.y, m.z);
}

inline float env_pdf(__global const float *row_pdf, __global const float *col_pdf, int w, int h,
                     float rotation, float3 d, int *pixel)
{
  float c = cos(rotation), sn = sin(rotation);
  float3 m = (float3)(c * d.x - sn * d.y, sn * d.x + c * d.y, d.z);
  float s = btf_mod((M_PI_F - atan2(m.y, m.x)) / (2.0f * M_PI_F), 1.0f);
  float t = acos(clamp(m.z, -1.0f, 1.0f)) / M_PI_F;
  int col = min((int)(s * w), w - 1), row = min((int)(t * h), h - 1);
  *pixel = row * w + col;
  float sin_t = fmax(sin(M_PI_F * t), 1e-9f);
  return row_pdf[row] * col_pdf[row * w + col] * w * h / (2.0f * M_PI_F * M_PI_F * sin_t);
}

__kernel void render_env_mis(const int width, const int height, const int row0,
                             __global const float *world_from_clip, const int tri_count,
                             __global const float *bounds, __global const int *links,
                             __global const float *corners, __global const int *tri_material,
                             __global const float *ints, __global const float *floats,
                             __global const int *material_offsets,
                             __global const float *material_params, const float eps,
                             __global const float *env, const int env_w, const int env_h,
                             const float2 env_params, __global const float *row_cdf,
                             __global const float *col_cdf, __global const float *row_pdf,
                             __global const float *col_pdf, const int samples, const uint seed,
                             __global float *combined)
{
  int x = get_global_id(0), yr = get_global_id(1);
  int y = row0 + yr;
  if (x >= width || y >= height) {
    return;
  }
  int px = yr * width + x;
  float2 ndc = (float2)((x + 0.5f) / width * 2.0f - 1.0f, 1.0f - (y + 0.5f) / height * 2.0f);
  float4 m0 = vload4(0, world_from_clip), m1 = vload4(1, world_from_clip);
  float4 m2 = vload4(2, world_from_clip), m3 = vload4(3, world_from_clip);
  float4 pn = (float4)(ndc, -1.0f, 1.0f), pf = (float4)(ndc, 1.0f, 1.0f);
  float4 near = (float4)(dot(m0, pn), dot(m1, pn), dot(m2, pn), dot(m3, pn));
  float4 far = (float4)(dot(m0, pf), dot(m1, pf), dot(m2, pf), dot(m3, pf));
  float3 o = near.xyz / near.w;
  float3 d = normalize(far.xyz / far.w - o);
  float t = 0.0f, bu = 0.0f, bv = 0.0f;
  int tri = tri_count > 0 ? trace(o, d, 0.0f, INFINITY, bounds, links, corners, false, &t, &bu, &bv)
                          : -1;
  if (tri < 0) {
    vstore4((float4)(env_lookup(env, env_w, env_h, env_params, d), 1.0f), px, combined);
    return;
  }
  __global const float *c = corners + 36 * tri;
  float w0 = 1.0f - bu - bv;
  float3 p = o + t * d;
  float3 lifted = (float3)(0.0f);
  for (int k = 0; k < 3; k++) {
    float3 pk = vload3(0, c + 12 * k), nk = normalize(vload3(0, c + 12 * k + 3));
    float3 tmp = p - pk;
    tmp -= fmin(dot(tmp, nk), 0.0f) * nk;
    lifted += (k == 0 ? w0 : (k == 1 ? bu : bv)) * (pk + tmp);
  }
  float3 n = normalize(w0 * vload3(0, c + 3) + bu * vload3(0, c + 15) + bv * vload3(0, c + 27));
  float2 uv = w0 * vload2(0, c + 6) + bu * vload2(0, c + 18) + bv * vload2(0, c + 30);
  float4 tg = w0 * vload4(0, c + 8) + bu * vload4(0, c + 20) + bv * vload4(0, c + 32);
  float3 wo_world = -d;
  float side = dot(n, wo_world) < 0.0f ? -1.0f : 1.0f;
  n *= side;
  float3 tt = tg.xyz - n * dot(n, tg.xyz);
  float tl = length(tt);
  tt = tl > 1e-8f ? tt / tl
                  : normalize(cross(fabs(n.z) < 0.9f ? (float3)(0, 0, 1) : (float3)(1, 0, 0), n));
  float3 b = cross(n, tt) * (c[11] < 0.0f ? -1.0f : 1.0f) * side;
  float3 wo = (float3)(dot(wo_world, tt), dot(wo_world, b), dot(wo_world, n));
  float2 view = btf_theta_phi_deg(wo);
  int mat = tri_material[tri];
  __global const float *I = ints + material_offsets[2 * mat];
  __global const float *F = floats + material_offsets[2 * mat + 1];
  __global const float *mp = material_params + 8 * mat;
  float2 buv = (float2)(mp[0] * uv.x + mp[2] * uv.y, mp[1] * uv.x + mp[3] * uv.y);
  float3 start = (side > 0.0f ? lifted : p) + n * eps;
  float rotation = env_params.x;
  uint rng = pcg_hash((uint)(y * width + x) ^ pcg_hash(seed));
  float3 sum = (float3)(0.0f);
  for (int si = 0; si < samples && wo.z > 0.0f; si++) {
    for (int strategy = 0; strategy < 2; strategy++) {
      float3 dir;
      float pdf_light, pdf_bsdf;
      int pixel;
      if (strategy == 0) { /* the environment's distribution */
        float u0 = rand01(&rng), u1 = rand01(&rng);
        int row = cdf_search(row_cdf, env_h, u0);
        float dt = (u0 - row_cdf[row]) / fmax(row_cdf[row + 1] - row_cdf[row], 1e-30f);
        __global const float *cc = col_cdf + row * (env_w + 1);
        int col = cdf_search(cc, env_w, u1);
        float ds = (u1 - cc[col]) / fmax(cc[col + 1] - cc[col], 1e-30f);
        dir = env_direction((col + clamp(ds, 0.0f, 0.999999f)) / env_w,
                            (row + clamp(dt, 0.0f, 0.999999f)) / env_h, rotation);
        pdf_light = env_pdf(row_pdf, col_pdf, env_w, env_h, rotation, dir, &pixel);
        float cos_n = dot(dir, n);
        pdf_bsdf = fmax(cos_n, 0.0f) / M_PI_F;
      }
      else { /* cosine-weighted about the shading normal */
        float u0 = rand01(&rng), u1 = rand01(&rng);
        float r = sqrt(u0), phi = 2.0f * M_PI_F * u1;
        float3 lo = (float3)(r * cos(phi), r * sin(phi), sqrt(fmax(1.0f - u0, 0.0f)));
        dir = lo.x * tt + lo.y * b + lo.z * n;
        pdf_bsdf = lo.z / M_PI_F;
        pdf_light = env_pdf(row_pdf, col_pdf, env_w, env_h, rotation, dir, &pixel);
      }
      float3 wi = (float3)(dot(dir, tt), dot(dir, b), dot(dir, n));
      float pdf_own = strategy == 0 ? pdf_light : pdf_bsdf;
      if (wi.z <= 0.0f || pdf_own <= 0.0f) {
        continue;
      }
#if HAS_SHADOWS
      float ts, us, vs;
      if (trace(start, dir, eps, INFINITY, bounds, links, corners, true, &ts, &us, &vs) >= 0) {
        continue;
      }
#endif
      float3 radiance = vload3(0, env + 4 * pixel) * env_params.y;
      float2 light = btf_theta_phi_deg(wi);
      float3 value = btf_evaluate(I, F, buv, wi, wo, light.x, light.y, view.x, view.y);
      float weight = pdf_own * pdf_own / (pdf_light * pdf_light + pdf_bsdf * pdf_bsdf);
      sum += value * radiance * (weight / pdf_own);
    }
  }
  vstore4((float4)(sum * (mp[4] / (float)max(samples, 1)), 1.0f), px, combined);
}