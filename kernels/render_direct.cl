/* Final render, deterministic direct-lighting mode: camera rays, the nearest surface, and exactly
 * the given virtual lights (no MIS, no bounces) — the common ground with the GLSL viewport.
 *
 * Variants: HAS_SHADOWS (shadow rays towards every light; off when the scene analysis proves no
 * surface can shadow another, btf_addon/scene/analysis.py); HAS_AREA_LIGHTS (the area-light
 * sampling code, off when the scene has none). Blender's lights: include/btf_lights.h.
 *
 * Passes written per pixel: combined (RGBA), depth (distance along the camera axis from the
 * camera, camera_forward.w = −dot(camera position, forward); 1e10 where
 * nothing is hit, as Blender), normal (world-space shading normal), uv (mesh UV). Rows
 * [row0, row0 + rows) are rendered, so the host can show progress and stop between bands.
 *
 * Anti-aliasing (aa_samples > 1): Combined is the mean over aa_samples rays through points of
 * the pixel filter's footprint: the R2 low-discrepancy points given (render/pixel_filter.py)
 * mapped through the filter's inverse-CDF table (include/btf_filter.h). With split_lights the
 * N lights are split into aa_samples consecutive blocks, one per subpixel, at the same offsets
 * in every pixel: the viewport's jittered passes when its batches hold as many lights. Else every subpixel sees all N, the
 * points rotated per pixel (Cranley-Patterson: one pattern everywhere would leave a structured
 * error instead of a falling one). The data passes stay at the pixel centre (a depth averaged
 * over an edge is no depth at all).
 *
 * Film › Transparent (transparent = 1, both kernels): the World is left out of Combined where
 * camera rays miss, and alpha is the filter-weighted share of rays that hit a surface
 * (premultiplied, as Cycles): 0 on the background, fractional along anti-aliased edges. The
 * World still lights the surfaces. */

#ifndef HAS_SHADOWS
#define HAS_SHADOWS 1
#endif
/* HAS_ENVIRONMENT 0: a black World (analysis.py): render_env_mis samples no environment. */
#ifndef HAS_ENVIRONMENT
#define HAS_ENVIRONMENT 1
#endif

#include "btf_packed.h"
/* btf_surface.h after btf_trace.h: its primary_hit traces. */
#include "btf_trace.h"
#include "btf_surface.h"
#include "btf_lights.h"
#include "btf_sampling.h"
#include "btf_filter.h"
#include "btf_launch.h"

/* cos and sin of the World's rotation; (1, 0) exactly for none, without the argument reduction
 * of PoCL's cos/sin (most Worlds are not rotated). */
inline float2 env_rotation(float angle)
{
  return angle == 0.0f ? (float2)(1.0f, 0.0f) : (float2)(cos(angle), sin(angle));
}

/* World direction d in the map's frame: the World's Z rotation undone (envmap.py: m = R_z(γ)·d). */
inline float3 env_map_vector(float3 d, float rotation)
{
  float2 cs = env_rotation(rotation);
  return (float3)(cs.x * d.x - cs.y * d.y, cs.y * d.x + cs.x * d.y, d.z);
}

/* The map's s across of map-frame vector m, in [0, 1] (1 only where atan2 gives −π). */
inline float env_map_s(float3 m)
{
  return (M_PI_F - btf_atan2(m.y, m.x)) / (2.0f * M_PI_F);
}

inline float3 env_lookup(__global const float *env, int w, int h, float2 params, float3 d)
{
  /* As shaders/env_lib.glsl: Blender's orientation, bilinear, wrapping in u. */
  float3 m = normalize(env_map_vector(d, params.x));
  float u = env_map_s(m);
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

/* Combined of one surface point lit by lights [first, first + count) (their mean) and Blender's
 * lights, times the material's exposure. */
inline float3 shade_direct(const SurfacePoint *sp, __global const float *ints,
                           __global const float *floats, __global const int *material_offsets,
                           __global const float *material_params, __global const float *lights,
                           int first, int count, float eps, __global const float *bounds,
                           __global const int *links, __global const float *corners,
                           __global const float *scene_lights, int scene_light_count)
{
  __global const float *I = ints + material_offsets[2 * sp->material];
  __global const float *F = floats + material_offsets[2 * sp->material + 1];
  float3 sum = (float3)(0.0f);
  if (sp->wo.z > 0.0f) {
    for (int i = first; i < first + count; i++) {
      float3 dir = vload3(0, lights + 8 * i);
      float3 wi = to_frame(sp, dir);
      if (wi.z <= 0.0f) {
        continue;
      }
#if HAS_SHADOWS
      if (!unoccluded(sp->start, dir, eps, INFINITY, bounds, links, corners)) {
        continue;
      }
#endif
      sum += btf_mapped(I, F, sp, wi) * vload3(0, lights + 8 * i + 4);
    }
  }
  sum /= (float)max(count, 1);
  if (sp->wo.z > 0.0f) {
    sum += blender_lights(sp, I, F, scene_lights, scene_light_count, eps, bounds, links, corners,
                          0);
  }
  return sum * sp->exposure;
}

/* Pixel (x, y) as the mean over aa_samples rays through the filter's footprint at the given
 * points in [0, 1)² (rotated per pixel); with split_lights subpixel s is lit by the s-th of aa_samples consecutive
 * blocks of the lights and weighs as many lights as its block holds. */
inline float4 shade_subpixels(int x, int y, int width, int height,
                              __global const float *world_from_clip, int tri_count,
                              __global const float *bounds, __global const int *links,
                              __global const float *corners, __global const int *tri_material,
                              __global const float *ints, __global const float *floats,
                              __global const int *material_offsets,
                              __global const float *material_params, __global const float *lights,
                              int n_lights, float eps, __global const float *env, int env_w,
                              int env_h, float2 env_params, __global const float *scene_lights,
                              int scene_light_count, __global const float *subpixels,
                              int aa_samples, int split_lights,
                              __global const float *filter_table, int transparent)
{
  /* Split lights: the same offsets in every pixel, in the viewport's order (its pass p adds
   * block p at offset p), so F12 is the converged viewport's image. All lights per subpixel:
   * rotated per pixel (fixed hash: still deterministic), so what remains is noise. */
  uint hash = pcg_hash((uint)(y * width + x) ^ 0x2545F491u);
  float2 rotation = split_lights ? (float2)(0.0f)
                                 : (float2)((float)(hash >> 8), (float)(pcg_hash(hash) >> 8)) /
                                       16777216.0f;
  float3 total = (float3)(0.0f);
  float coverage = 0.0f; /* the weight of subpixels that hit a surface: Film › Transparent's alpha */
  for (int s = 0; s < aa_samples; s++) {
    int first = split_lights ? s * n_lights / aa_samples : 0;
    int count = split_lights ? (s + 1) * n_lights / aa_samples - first : n_lights;
    float weight = split_lights ? (float)count / (float)max(n_lights, 1)
                                : 1.0f / (float)aa_samples;
    float2 u = vload2(s, subpixels) + rotation;
    u -= floor(u);
    float2 raster = (float2)(x + 0.5f, y + 0.5f) + filter_sample(filter_table, u);
    float3 o, d;
    float t, bu, bv;
    int tri = primary_hit_at(raster, width, height, world_from_clip, tri_count, bounds, links,
                             corners, &o, &d, &t, &bu, &bv);
    if (tri < 0) {
      if (!transparent) { /* a transparent film has no World behind the surfaces */
        total += weight * env_lookup(env, env_w, env_h, env_params, d);
      }
      continue;
    }
    coverage += weight;
    SurfacePoint sp = surface_point(o, d, t, bu, bv, tri, corners, tri_material,
                                    material_params, eps);
    total += weight * shade_direct(&sp, ints, floats, material_offsets, material_params, lights,
                                   first, count, eps, bounds, links, corners, scene_lights,
                                   scene_light_count);
  }
  return (float4)(total, coverage);
}

__kernel void render_direct(const int width, const int height, const int row0,
                            __global const float *world_from_clip, const float4 camera_forward,
                            const int tri_count, __global const float *bounds,
                            __global const int *links, __global const float *corners,
                            __global const int *tri_material, __global const float *ints,
                            __global const float *floats, __global const int *material_offsets,
                            __global const float *material_params, __global const float *lights,
                            const int n_lights, const float eps, __global const float *env,
                            const int env_w, const int env_h, const float2 env_params,
                            __global const float *scene_lights, const int scene_light_count,
                            __global const float *subpixels, const int aa_samples,
                            const int split_lights, __global const float *filter_table,
                            const int transparent, __global float *combined,
                            __global float *depth,
                            __global float *normal_out, __global float *uv_out)
{
  int x, yr;
  launch_pixel(&x, &yr); /* spread over the band: include/btf_launch.h */
  int y = row0 + yr;
  if (x >= width || y >= height) {
    return;
  }
  int px = yr * width + x; /* index inside this band's buffers */
  float3 o, d;
  float t, bu, bv;
  int tri = primary_hit(x, y, width, height, world_from_clip, tri_count, bounds, links, corners,
                        &o, &d, &t, &bu, &bv);
  if (tri < 0) {
    /* Film › Transparent: premultiplied, so the World is 0 with alpha 0 (as Cycles). */
    float4 world = transparent ? (float4)(0.0f)
                               : (float4)(env_lookup(env, env_w, env_h, env_params, d), 1.0f);
    if (aa_samples > 1) { /* an edge may still cross the filter's footprint */
      world = shade_subpixels(x, y, width, height, world_from_clip, tri_count, bounds, links,
                              corners, tri_material, ints, floats, material_offsets,
                              material_params, lights, n_lights, eps, env, env_w, env_h,
                              env_params, scene_lights, scene_light_count, subpixels, aa_samples,
                              split_lights, filter_table, transparent);
      world.w = transparent ? world.w : 1.0f; /* alpha: coverage on a transparent film */
    }
    vstore4(world, px, combined);
    depth[px] = 1e10f;
    vstore3((float3)(0.0f), px, normal_out);
    vstore2((float2)(0.0f), px, uv_out);
    return;
  }
  SurfacePoint sp = surface_point(o, d, t, bu, bv, tri, corners, tri_material, material_params,
                                  eps);
  float4 sum =
      aa_samples > 1
          ? shade_subpixels(x, y, width, height, world_from_clip, tri_count, bounds, links,
                            corners, tri_material, ints, floats, material_offsets,
                            material_params, lights, n_lights, eps, env, env_w, env_h, env_params,
                            scene_lights, scene_light_count, subpixels, aa_samples, split_lights,
                            filter_table, transparent)
          : (float4)(shade_direct(&sp, ints, floats, material_offsets, material_params, lights, 0,
                                  n_lights, eps, bounds, links, corners, scene_lights,
                                  scene_light_count),
                     1.0f);
  sum.w = transparent ? sum.w : 1.0f; /* alpha: coverage on a transparent film */
  vstore4(sum, px, combined);
  depth[px] = dot(sp.p, camera_forward.xyz) + camera_forward.w; /* distance along the camera axis */
  vstore3(sp.n, px, normal_out);
  vstore2(sp.uv, px, uv_out);
}

/* --- Monte Carlo environment lighting with MIS ----------------------------------------------
 * The same camera rays and shading frame as render_direct, but the World is sampled
 * continuously: per sample one light direction drawn from the environment's piecewise-constant
 * distribution (btf_addon/core/sampling/envmap.py, same tables; at a glossy camera vertex one
 * more from the map's sun, where it has one) and one direction from the BTF's sampling
 * (cosine, or its GGX lobe where it has one: include/btf_sampling.h), combined
 * with the power heuristic. Unbiased for any BTF; converges to the integral the virtual lights
 * approximate. The host renders samples [first_sample, first_sample + samples) per launch and
 * averages launches; a sample's random points depend only on its index, not on the split. */

/* The world direction of map point (s, t), and sin θ there (its density's factor). One sincos
 * per angle: PoCL's sin and cos each reduce their argument (__pocl_argReductionS, 7 % of a
 * Lambertian sample's time when this took four calls and the density a fifth). */
inline float3 env_direction(float s, float t, float rotation, float *sin_theta)
{
  float theta = M_PI_F * t, phi = M_PI_F - 2.0f * M_PI_F * s;
  float cos_theta, cos_phi;
  float st = sincos(theta, &cos_theta), sin_phi = sincos(phi, &cos_phi);
  *sin_theta = st;
  float3 m = (float3)(st * cos_phi, st * sin_phi, cos_theta);
  float2 cs = env_rotation(rotation); /* world = R(-rotation) · map */
  float c = cs.x, sn = cs.y;
  return (float3)(c * m.x + sn * m.y, -sn * m.x + c * m.y, m.z);
}

/* The solid-angle density of drawing a map pixel with `probability` and a point uniformly in
 * it, at sin θ of the point (the pixel's image-plane density over the sphere's 2π² sin θ). */
inline float pixel_density(float probability, int w, int h, float sin_t)
{
  return probability * w * h / (2.0f * M_PI_F * M_PI_F * fmax(sin_t, 1e-9f));
}

/* The density of the environment's sampling in one pixel. */
inline float env_pixel_pdf(__global const float *row_pdf, __global const float *col_pdf, int w,
                           int h, int row, int col, float sin_t)
{
  return pixel_density(row_pdf[row] * col_pdf[row * w + col], w, h, sin_t);
}

/* The power heuristic's weight of a strategy of density `own` among up to four (Veach 1997;
 * a strategy not drawn at this vertex passes 0). */
inline float power_weight(float own, float a, float b, float c)
{
  return own * own / (own * own + a * a + b * b + c * c);
}

/* A point in one of the map's pixels for uniform u: the pixel by the tables' CDFs, the point
 * uniformly in it; its world direction, pixel and sin θ. */
inline float3 table_draw(float2 u, __global const float *row_cdf, __global const float *col_cdf,
                         int w, int h, float rotation, int *pixel, float *sin_t)
{
  int row = cdf_search(row_cdf, h, u.x);
  float dt = (u.x - row_cdf[row]) / fmax(row_cdf[row + 1] - row_cdf[row], 1e-30f);
  __global const float *cc = col_cdf + row * (w + 1);
  int col = cdf_search(cc, w, u.y);
  float ds = (u.y - cc[col]) / fmax(cc[col + 1] - cc[col], 1e-30f);
  *pixel = row * w + col;
  return env_direction((col + clamp(ds, 0.0f, 0.999999f)) / w,
                       (row + clamp(dt, 0.0f, 0.999999f)) / h, rotation, sin_t);
}

/* The density of the first next-event draw at a pixel: `table`, the tables' density there (the
 * map without its sun, where it has one), and, with probability `share`, the sun's. */
inline float next_event_density(float table, __global const float *sun_probability, int w,
                                int h, int pixel, float sin_t, float share)
{
  return share > 0.0f
             ? (1.0f - share) * table + share * pixel_density(sun_probability[pixel], w, h, sin_t)
             : table;
}

/* The tables' density at a map pixel. */
inline float table_density(__global const float *row_pdf, __global const float *col_pdf, int w,
                           int h, int pixel, float sin_t)
{
  int row = pixel / w;
  return env_pixel_pdf(row_pdf, col_pdf, w, h, row, pixel - row * w, sin_t);
}

/* The same from the sun's pixels (envmap.py SunTable): one by its CDF, the point uniformly. */
inline float3 sun_draw(float2 u, __global const float *sun_cdf, __global const int *sun_pixels,
                       int sun_count, int w, int h, float rotation, int *pixel, float *sin_t)
{
  int k = cdf_search(sun_cdf, sun_count, u.x);
  float dt = (u.x - sun_cdf[k]) / fmax(sun_cdf[k + 1] - sun_cdf[k], 1e-30f);
  int row = sun_pixels[k] / w, col = sun_pixels[k] - row * w;
  *pixel = sun_pixels[k];
  return env_direction((col + clamp(u.y, 0.0f, 0.999999f)) / w,
                       (row + clamp(dt, 0.0f, 0.999999f)) / h, rotation, sin_t);
}

inline float env_pdf(__global const float *row_pdf, __global const float *col_pdf, int w, int h,
                     float rotation, float3 d, int *pixel, float *sin_theta)
{
  float3 m = env_map_vector(d, rotation);
  float s = btf_mod(env_map_s(m), 1.0f);
  float z = clamp(m.z, -1.0f, 1.0f);
  float t = acos(z) / M_PI_F;
  int col = min((int)(s * w), w - 1), row = min((int)(t * h), h - 1);
  *pixel = row * w + col;
  /* sin θ = sin(acos z) = √((1 − z)(1 + z)): exact factors, no cancellation at the poles */
  float sin_t = sqrt(fmax((1.0f - z) * (1.0f + z), 0.0f));
  *sin_theta = sin_t;
  return env_pixel_pdf(row_pdf, col_pdf, w, h, row, col, sin_t);
}

#include "btf_env_window.h"

/* A path's indirect light (everything after its first bounce) scaled so that no channel exceeds
 * `limit` (Cycles' Clamp Indirect: limit 0 is off). Bright, rare paths (a small light source
 * seen through a glossy bounce) otherwise stay as fireflies for thousands of samples; the
 * clamp trades them for a bias, measured in docs/accuracy.md. */
inline float3 clamp_indirect(float3 light, float limit)
{
  float peak = fmax(light.x, fmax(light.y, light.z));
  return limit > 0.0f && peak > limit ? light * (limit / peak) : light;
}

#include "btf_path.h"

/* The Sobol dimension of the film's 2D point: far beyond any path's own decisions. */
#define FILM_DIMENSION 0xFFFFu

/* A GGX lobe this sharp (alpha² below; GGX roughness ≈ 0.21 in Blender's convention α = r²)
 * takes a camera ray per sample whatever Samples per Camera Ray asks: its light comes smoothly
 * (a sun drawn on its own, a smooth sky through a narrow lobe), and what is left is its
 * highlight moving across the pixel's footprint, which only more camera rays resolve. The GGX
 * sphere of roughness 0.2 under city.exr: 4.9× less time to the same error at 64 samples, 1.5×
 * at 256; the demo's roughness 0.35 sphere lost 1.3× this way, so the line lies between
 * (docs/accuracy.md, "Samples per camera ray"). */
#define SHARP_LOBE_ALPHA2 0.002f

/* Whether the surface through the pixel's centre has a sharp GGX lobe that carries its light
 * (the GGX codec, a fully metallic Principled): a deterministic ray, the same in every launch,
 * so the choice it makes is fixed before any sample and keeps every sample unbiased. */
inline bool sharp_lobe_at_centre(int x, int y, int width, int height,
                                 __global const float *world_from_clip, int tri_count,
                                 __global const float *bounds, __global const int *links,
                                 __global const float *corners, __global const int *tri_material,
                                 __global const float *ints, __global const float *floats,
                                 __global const int *material_offsets,
                                 __global const float *material_params)
{
  float3 o, d;
  float t, bu, bv;
  int tri = primary_hit(x, y, width, height, world_from_clip, tri_count, bounds, links, corners,
                        &o, &d, &t, &bu, &bv);
  if (tri < 0) {
    return false;
  }
  int m = (int)material_params[MATERIAL_BLOCK_FLOATS * tri_material[tri] + M_MATERIAL];
  __global const float *I = ints + material_offsets[2 * m];
  __global const float *F = floats + material_offsets[2 * m + 1];
  return ggx_lobe_probability(I, F) >= 0.9f && FTAB(F_ALPHA2) < SHARP_LOBE_ALPHA2;
}

/* Adaptive sampling's half buffer (render/adaptive.py): whether sample `index` is one of the
 * half whose mean is compared with the mean of all. Cycles' class A (Christensen et al.,
 * "Progressive Multi-Jittered Sample Sequences", §10.2.1): the parity of the odd bits, so each
 * aligned block of 4 is split 2 : 2 and both halves stay well stratified in every Sobol
 * dimension (odd indices alone would all lie in one half of the first dimension). Counted in
 * camera-ray groups where samples share a ray, so that the halves differ by their edges too. */
inline bool in_half(uint index, int camera_split, int filtered)
{
  uint unit = filtered ? index / (uint)camera_split : index;
  return (popcount(unit & 0xAAAAAAAAu) & 1u) != 0u;
}

__kernel void render_env_mis(const int width, const int height, const int row0,
                             __global const float *world_from_clip, const int tri_count,
                             __global const float *bounds, __global const int *links,
                             __global const float *corners, __global const int *tri_material,
                             __global const float *ints, __global const float *floats,
                             __global const int *material_offsets,
                             __global const float *material_params, const float eps,
                             __global const float *env, const int env_w, const int env_h,
                             const float2 env_params, __global const float *scene_lights,
                             const int scene_light_count, __global const float *row_cdf,
                             __global const float *col_cdf, __global const float *row_pdf,
                             __global const float *col_pdf, __global const float *sun_cdf,
                             __global const int *sun_pixels,
                             __global const float *sun_probability, const int sun_count,
                             const float sun_share, __global const float *window_row_pdf,
                             __global const float *window_cdf, const int window_block,
                             const int first_sample,
                             const int samples, const uint seed,
                             const int max_bounces, const float indirect_limit,
                             const int camera_split, const int filtered,
                             __global const float *filter_table,
                             const int transparent, __global float *combined,
                             __global float *half_sums, __global const uchar *active,
                             const int adaptive)
{
  int x, yr;
  launch_pixel(&x, &yr); /* spread over the band: include/btf_launch.h */
  int y = row0 + yr;
  if (x >= width || y >= height) {
    return;
  }
  int px = yr * width + x;
  /* Adaptive sampling: `half_sums` gets the sum of the launch's samples in_half and their count;
   * a pixel that has converged (active 0, a whole-image mask) costs nothing more. */
  if (adaptive && !active[y * width + x]) {
    vstore4((float4)(0.0f), px, combined);
    vstore4((float4)(0.0f), px, half_sums);
    return;
  }
  float3 o, d;
  float t, bu, bv;
  /* Anti-aliasing (filtered): a camera ray through its own point of the pixel filter's
   * footprint (include/btf_filter.h), drawn from a Sobol dimension of its own, so the path's
   * other decisions are those of the pixel-centre render. Samples index, index + 1, … of one
   * group of camera_split share the group's camera ray and shading point (its point is that
   * of Sobol index index / camera_split): the camera ray and the surface it meets cost more
   * than a diffuse sample's lighting, and within a pixel's footprint the light varies more
   * than the surface, so the saved time buys more samples than the shared points cost
   * (docs/accuracy.md, "Samples per camera ray"). Every sample stays an unbiased estimate.
   * A pixel under a sharp GGX lobe takes one sample per group (sharp_lobe_at_centre). */
  int tri = filtered ? -1
                     : primary_hit(x, y, width, height, world_from_clip, tri_count, bounds,
                                   links, corners, &o, &d, &t, &bu, &bv);
  if (!filtered && tri < 0) { /* Film › Transparent: premultiplied 0, as Cycles */
    float4 world = transparent ? (float4)(0.0f)
                               : (float4)(env_lookup(env, env_w, env_h, env_params, d), 1.0f);
    vstore4(world, px, combined);
    if (adaptive) { /* every sample sees the same World: the half's mean is the same */
      int halved = 0;
      for (int si = 0; si < samples; si++) {
        halved += in_half((uint)(first_sample + si), camera_split, filtered);
      }
      vstore4((float4)(world.xyz * (float)halved, (float)halved), px, half_sums);
    }
    return;
  }
  SurfacePoint sp;
  if (!filtered) {
    sp = surface_point(o, d, t, bu, bv, tri, corners, tri_material, material_params, eps);
  }
  int split = camera_split; /* this pixel's: 1 under a sharp lobe (SHARP_LOBE_ALPHA2) */
  if (filtered && split > 1 &&
      sharp_lobe_at_centre(x, y, width, height, world_from_clip, tri_count, bounds, links,
                           corners, tri_material, ints, floats, material_offsets,
                           material_params)) {
    split = 1;
  }
  PathScene ps = {bounds, links, corners, tri_material,       /* the scene */
                  ints, floats, material_offsets, material_params, eps,
                  env, env_w, env_h, env_params,                  /* the World */
                  scene_lights, scene_light_count,                /* Blender's lights */
                  row_cdf, col_cdf, row_pdf, col_pdf,             /* the World's tables */
                  sun_cdf, sun_pixels, sun_probability, sun_count, sun_share,
                  window_row_pdf, window_cdf, window_block,
                  max_bounces, indirect_limit};                   /* the path's limits */
  uint pixel_seed = pcg_hash((uint)(y * width + x) ^ pcg_hash(seed));
  float3 sum = (float3)(0.0f);
  float3 sky = (float3)(0.0f); /* the World seen by the current camera ray, where it misses */
  int hits = 0; /* samples whose camera ray met a surface: Film › Transparent's alpha */
  float3 half_sum = (float3)(0.0f);
  int half_count = 0;
  for (int si = 0; si < samples; si++) {
    uint index = (uint)(first_sample + si); /* a sample's points depend only on its index */
    /* The sample's own light is sum - before: `sum` adds as it always did, so an image with
     * adaptive sampling off is bit for bit the one of before. */
    float3 before = sum;
    bool halved = adaptive && in_half(index, split, filtered);
    half_count += halved;
    Sampler smp = {pixel_seed, index, 0u, pcg_hash(pixel_seed + index)};
    /* A launch may start inside a group: its first sample traces the group's ray again. */
    if (filtered && (si == 0 || index % (uint)split == 0u)) {
      Sampler film = {pixel_seed, index / (uint)split, FILM_DIMENSION, 0u};
      float2 raster = (float2)(x + 0.5f, y + 0.5f) +
                      filter_sample(filter_table, next_2d(&film));
      tri = primary_hit_at(raster, width, height, world_from_clip, tri_count, bounds, links,
                           corners, &o, &d, &t, &bu, &bv);
      if (tri >= 0) {
        sp = surface_point(o, d, t, bu, bv, tri, corners, tri_material, material_params, eps);
      }
      else if (!transparent) { /* looked up once for the group's samples, which all see it */
        sky = env_lookup(env, env_w, env_h, env_params, d);
      }
    }
    if (filtered && tri < 0) {
      if (!transparent) {
        sum += sky;
      }
      if (halved) {
        half_sum += sum - before;
      }
      continue;
    }
    hits++;
    path_light(&ps, sp, &smp, &sum);
    if (halved) {
      half_sum += sum - before;
    }
  }
  float alpha = transparent ? (float)hits / (float)max(samples, 1) : 1.0f;
  vstore4((float4)(sum / (float)max(samples, 1), alpha), px, combined);
  if (adaptive) {
    vstore4((float4)(half_sum, (float)half_count), px, half_sums);
  }
}
#include "btf_bake.h"
#include "btf_lobe.h"

/* --- The light bake (btf_addon/cl/bake.py; docs/accuracy.md "The light bake") ---------------
 * Per bake point and view bin: F12's own paths (path_light) from points of the bake point's
 * footprint (its neighbourhood on the surface, btf_addon/scene/bake_points.py) towards the
 * bin's direction, and beside them the material's response at the same points to one light
 * from the point's mean light direction (bake_light_direction below, traced first). Their ratio
 * is the light per unit of that response: playback multiplies it
 * by the response at the pixel's own texel, decoded live, so the bake carries the light
 * (centimetres coarse) and the live decode the material's detail (0.1 mm). An analytic
 * material's response is its unshadowed light, the same paths through an empty scene without
 * bounces: playback multiplies the ratio (shadows and interreflection) by that light computed
 * per pixel (include/btf_lobe.h), so a glossy lobe follows the view exactly. Sums are written
 * (xyz; w: the samples counted), the host adds launches. Points [point0, point_end) index the
 * footprints given (a subset of the grid's points: a re-bake traces only the stale meshes');
 * point_ids gives each one's index in the whole grid, which seeds its paths, so a point gets the
 * same random numbers whichever subset is baked: a partial re-bake equals a full one there. */

/* Sample `index` of bake point p's footprint, seen from the normal's side (the frame
 * surface_point builds faces it); false where the footprint holds no triangle of the scene.
 * The footprint position by a hash of the index, not index mod F: the Sobol points of indices
 * ≡ k mod 2^m share their leading bits, so a fixed stride would light each position from one
 * stratum of the sky only. */
inline bool bake_footprint_point(int p, int footprint, __global const int *foot_tri,
                                 __global const float *foot_bary, uint point_seed, uint index,
                                 int tri_count, __global const float *corners,
                                 __global const int *tri_material,
                                 __global const float *material_params, float eps,
                                 SurfacePoint *sp)
{
  int pick = p * footprint + (int)(pcg_hash(index ^ point_seed ^ 0x68E31DA4u) % (uint)footprint);
  int tri = foot_tri[pick];
  if (tri < 0 || tri >= tri_count) {
    return false;
  }
  float2 bary = vload2(pick, foot_bary);
  __global const float *c = corners + 36 * tri;
  float w0 = 1.0f - bary.x - bary.y;
  float3 pos = w0 * vload3(0, c) + bary.x * vload3(0, c + 12) + bary.y * vload3(0, c + 24);
  float3 n = w0 * vload3(0, c + 3) + bary.x * vload3(0, c + 15) + bary.y * vload3(0, c + 27);
  if (!(length(n) > 1e-12f)) { /* opposite corner normals: the face's own */
    n = cross(vload3(0, c + 12) - vload3(0, c), vload3(0, c + 24) - vload3(0, c));
  }
  n = normalize(n);
  *sp = surface_point(pos + n, -n, 1.0f, bary.x, bary.y, tri, corners, tri_material,
                      material_params, eps);
  return true;
}

/* Per bake point, the light its footprint receives as (Σ E·wi, Σ E): E the luminance of the
 * irradiance along wi, wi in the point's frame; its direction is the point's light direction
 * (btf_bake.h bake_response; cl/bake.py light_directions). The World is drawn from its plain
 * table (row_cdf … col_pdf: envmap.py Environment.tables, whose draws reach every direction
 * with light, where the final render's compensated tables leave the dim sky to the BTF's
 * draws) and Blender's lights one point each, both behind whatever occludes them. Light from
 * other surfaces is left out: it is dim beside the World's, and would cost a path. */
__kernel void bake_light_direction(const int point0, const int point_end, const int footprint,
                                   __global const int *foot_tri,
                                   __global const float *foot_bary,
                                   __global const int *point_ids, const int tri_count,
                                   __global const float *bounds, __global const int *links,
                                   __global const float *corners,
                                   __global const int *tri_material,
                                   __global const float *ints, __global const float *floats,
                                   __global const int *material_offsets,
                                   __global const float *material_params, const float eps,
                                   __global const float *env, const int env_w, const int env_h,
                                   const float2 env_params, __global const float *scene_lights,
                                   const int scene_light_count, __global const float *row_cdf,
                                   __global const float *col_cdf, __global const float *row_pdf,
                                   __global const float *col_pdf, const int samples,
                                   const uint seed, __global float *sums)
{
  int local_point = get_global_id(0);
  int p = point0 + local_point;
  if (p >= point_end) {
    return;
  }
  const float3 luminance = (float3)(0.2126f, 0.7152f, 0.0722f); /* envmap.LUMINANCE */
  uint point_seed = pcg_hash((uint)point_ids[p] ^ pcg_hash(seed ^ 0x3C6EF372u));
  float3 towards = (float3)(0.0f);
  float total = 0.0f;
  for (int si = 0; si < samples; si++) {
    SurfacePoint sp;
    if (!bake_footprint_point(p, footprint, foot_tri, foot_bary, point_seed, (uint)si,
                              tri_count, corners, tri_material, material_params, eps, &sp)) {
      continue;
    }
    Sampler smp = {point_seed, (uint)si, 0u, pcg_hash(point_seed + (uint)si)};
#if HAS_ENVIRONMENT
    {
      int pixel;
      float sin_t;
      float3 dir = table_draw(next_2d(&smp), row_cdf, col_cdf, env_w, env_h, env_params.x,
                              &pixel, &sin_t);
      float pdf = table_density(row_pdf, col_pdf, env_w, env_h, pixel, sin_t);
      float3 wi = to_frame(&sp, dir);
      bool visible = wi.z > 0.0f && pdf > 0.0f;
#if HAS_SHADOWS
      visible = visible && unoccluded(sp.start, dir, eps, INFINITY, bounds, links, corners);
#endif
      if (visible) {
        float e = dot(vload3(0, env + 4 * pixel), luminance) * env_params.y * wi.z / pdf;
        towards += e * wi;
        total += e;
      }
    }
#endif
    for (int i = 0; i < scene_light_count; i++) {
      __global const float *L = scene_lights + LIGHT_FLOATS * i;
      float3 dir;
      float dist;
      float e = dot(light_sample(L, sp.start, next_2d(&smp), true, &dir, &dist), luminance);
      float3 wi = to_frame(&sp, dir);
      bool visible = wi.z > 0.0f && e > 0.0f;
#if HAS_SHADOWS
      float tmax = isinf(dist) ? INFINITY : dist * (1.0f - 1e-4f);
      visible = visible && unoccluded(sp.start, dir, eps, tmax, bounds, links, corners);
#endif
      if (visible) {
        towards += e * wi.z * wi;
        total += e * wi.z;
      }
    }
  }
  vstore4((float4)(towards, total), local_point, sums);
}

/* Per bake point and view bin, the sums of F12's light and of the unit it is per (the block
 * comment above): `light_dirs` holds each point's light direction (float4 rows, unit xyz). */
__kernel void bake_light(const int point0, const int point_end, const int bin_count,
                         const int footprint, __global const int *foot_tri,
                         __global const float *foot_bary, __global const int *point_ids,
                         __global const float *bin_dirs,
                         const int tri_count, __global const float *bounds,
                         __global const int *links, __global const float *corners,
                         __global const int *tri_material, __global const float *ints,
                         __global const float *floats, __global const int *material_offsets,
                         __global const float *material_params, const float eps,
                         __global const float *env, const int env_w, const int env_h,
                         const float2 env_params, __global const float *scene_lights,
                         const int scene_light_count, __global const float *row_cdf,
                         __global const float *col_cdf, __global const float *row_pdf,
                         __global const float *col_pdf, __global const float *sun_cdf,
                         __global const int *sun_pixels, __global const float *sun_probability,
                         const int sun_count, const float sun_share,
                         __global const float *window_row_pdf, __global const float *window_cdf,
                         const int window_block, const int first_sample, const int samples,
                         const uint seed, const int max_bounces, const float indirect_limit,
                         __global const float *open_bounds, __global const int *open_links,
                         __global const float *open_corners,
                         __global const float *light_dirs, __global float *radiance,
                         __global float *response)
{
  int local_point = get_global_id(0), bin = get_global_id(1);
  int p = point0 + local_point;
  if (p >= point_end || bin >= bin_count) { /* points [point0, point_end) in this launch */
    return;
  }
  PathScene ps = {bounds, links, corners, tri_material,       /* the scene */
                  ints, floats, material_offsets, material_params, eps,
                  env, env_w, env_h, env_params,                  /* the World */
                  scene_lights, scene_light_count,                /* Blender's lights */
                  row_cdf, col_cdf, row_pdf, col_pdf,             /* the World's tables */
                  sun_cdf, sun_pixels, sun_probability, sun_count, sun_share,
                  window_row_pdf, window_cdf, window_block,
                  max_bounces, indirect_limit};                   /* the path's limits */
  /* The same World with nothing in it and no bounces: an analytic point's unshadowed light
   * (open_*: a BVH of one degenerate triangle, cl/renderer.py open_bvh). */
  PathScene open = ps;
  open.bounds = open_bounds, open.links = open_links, open.corners = open_corners;
  open.max_bounces = 0;
  float3 wo = vload3(0, bin_dirs + 4 * bin);
  /* unsigned: defined past 2^31, where an int's overflow is not (the same value below it) */
  uint point_seed = pcg_hash(((uint)point_ids[p] * (uint)bin_count + (uint)bin) ^ pcg_hash(seed));
  float3 light_dir = vload3(0, light_dirs + 4 * p); /* bake_light_direction's, made unit */
  float3 light = (float3)(0.0f), unit = (float3)(0.0f);
  int counted = 0;
  for (int si = 0; si < samples; si++) {
    uint index = (uint)(first_sample + si);
    SurfacePoint sp;
    if (!bake_footprint_point(p, footprint, foot_tri, foot_bary, point_seed, index, tri_count,
                              corners, tri_material, material_params, eps, &sp)) {
      continue;
    }
    sp.wo = wo;
    Sampler smp = {point_seed, index, 0u, pcg_hash(point_seed + index)};
    Sampler open_smp = smp; /* the same random numbers: the ratio's noise mostly cancels */
    path_light(&ps, sp, &smp, &light);
    __global const float *I = ints + material_offsets[2 * sp.material];
    __global const float *F = floats + material_offsets[2 * sp.material + 1];
    if (bake_over_unshadowed(I)) {
      path_light(&open, sp, &open_smp, &unit);
    }
    else {
      unit += bake_response(I, F, &sp, light_dir);
    }
    counted++;
  }
  int out = local_point * bin_count + bin;
  vstore4((float4)(light, (float)counted), out, radiance);
  vstore4((float4)(unit, (float)counted), out, response);
}


/* A frame lit by a light bake, as the drawer plays it back: per subpixel of the film (as
 * render_direct's anti-aliasing, all subpixels at the given offsets rotated per pixel) the
 * baked light per unit response at the surface point and view, times the response decoded
 * live at the point's own texel. The World where camera rays miss. Combined only. */
__kernel void render_baked(const int width, const int height, const int row0,
                           __global const float *world_from_clip, const int tri_count,
                           __global const float *bounds, __global const int *links,
                           __global const float *corners, __global const int *tri_material,
                           __global const float *ints, __global const float *floats,
                           __global const int *material_offsets,
                           __global const float *material_params, const float eps,
                           __global const float *env, const int env_w, const int env_h,
                           const float2 env_params, __global const int *tri_cuts,
                           __global const int *tri_first, __global const int *tri_points,
                           __global const float *baked, const int view_bins,
                           __global const float *subpixels, const int aa_samples,
                           __global const float *filter_table, const int transparent,
                           const int times_response, __global const float *pyramid,
                           const int pyramid_levels, __global const float *scene_lights,
                           const int scene_light_count, __global const float *open_bounds,
                           __global const int *open_links, __global const float *open_corners,
                           const int lobe_samples, __global float *combined)
{
  int x, yr;
  launch_pixel(&x, &yr);
  int y = row0 + yr;
  if (x >= width || y >= height) {
    return;
  }
  uint hash = pcg_hash((uint)(y * width + x) ^ 0x2545F491u);
  float2 rotation = aa_samples > 1 ? (float2)((float)(hash >> 8), (float)(pcg_hash(hash) >> 8)) /
                                         16777216.0f
                                   : (float2)(0.0f);
  float3 total = (float3)(0.0f);
  float coverage = 0.0f;
  for (int s = 0; s < aa_samples; s++) {
    float2 u = vload2(s, subpixels) + rotation;
    u -= floor(u);
    float2 raster = (float2)(x + 0.5f, y + 0.5f) +
                    (aa_samples > 1 ? filter_sample(filter_table, u) : (float2)(0.0f));
    float3 o, d;
    float t, bu, bv;
    int tri = primary_hit_at(raster, width, height, world_from_clip, tri_count, bounds, links,
                             corners, &o, &d, &t, &bu, &bv);
    if (tri < 0) {
      if (!transparent) {
        total += env_lookup(env, env_w, env_h, env_params, d);
      }
      continue;
    }
    coverage += 1.0f;
    SurfacePoint sp = surface_point(o, d, t, bu, bv, tri, corners, tri_material,
                                    material_params, eps);
    if (sp.wo.z <= 0.0f) {
      continue;
    }
    __global const float *I = ints + material_offsets[2 * sp.material];
    __global const float *F = floats + material_offsets[2 * sp.material + 1];
    float3 light_dir;
    float3 value = bake_lookup(tri_cuts, tri_first, tri_points, baked, view_bins, tri, bu, bv,
                               sp.wo, &light_dir);
    /* times_response 0: the baked values themselves (a comparison's ratio image); an
     * analytic point's unit is its unshadowed light, subpixel s the drawer's frame s */
    float3 unit = !times_response              ? (float3)(1.0f)
                  : !bake_over_unshadowed(I) ? bake_response(I, F, &sp, light_dir)
                                             : lobe_light(I, F, &sp, pyramid, env_w, env_h,
                                                          pyramid_levels, env_params.x,
                                                          scene_lights, scene_light_count, eps,
                                                          open_bounds, open_links, open_corners,
                                                          (uint)s, lobe_samples);
    total += unit * value;
  }
  float n = (float)max(aa_samples, 1);
  vstore4((float4)(total / n, transparent ? coverage / n : 1.0f), yr * width + x, combined);
}
