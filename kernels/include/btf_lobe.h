/* An analytic material's unshadowed light from the World and Blender's lights, converged per
 * pixel: what the light bake's ratio multiplies on an analytic object (docs/accuracy.md "The
 * light bake played back"). shaders/lobe_lib.glsl is this code line for line; both read the
 * World's pyramid (btf_addon/core/sampling/world_pyramid.py documents its layout).
 *
 * Filtered importance sampling (Křivánek and Colbert 2008): `samples` directions from the
 * material's own mixture (its GGX lobe's visible normals and a cosine share, as F12 draws them:
 * include/btf_sampling.h), each reading the World averaged over its share of the sphere,
 * 1 / (samples · pdf), at the pyramid level whose pixels cover it (LOBE_LOD_BIAS levels
 * coarser). The directions are the R3 sequence's points frame·samples … + samples − 1
 * (Roberts 2018), in fixed point so both back ends compute the same bits: every pixel uses the
 * same frame's set, frames continue the sequence, so what a still head accumulates is one
 * low-discrepancy set. */
#ifndef BTF_LOBE_H
#define BTF_LOBE_H

#ifndef LOBE_LOD_BIAS /* core/sampling/world_pyramid.py */
#error LOBE_LOD_BIAS missing: build through btf_addon/cl/renderer.py
#endif

/* Point i of the R3 sequence, 0.5 + i·(1/φ₃, 1/φ₃², 1/φ₃³) mod 1, with 24 bits. */
inline float3 lobe_point(uint i)
{
  uint x = 2147483648u + i * 3518319155u, y = 2147483648u + i * 2882110345u;
  uint z = 2147483648u + i * 2360945575u;
  return (float3)((float)(x >> 8), (float)(y >> 8), (float)(z >> 8)) / 16777216.0f;
}

/* The first row of level k (levels stacked top to bottom from level 0's height h). */
inline int pyramid_row(int h, int k)
{
  int row = 0;
  for (int j = 0; j < k; j++) {
    row += max(h >> j, 1);
  }
  return row;
}

inline float3 pyramid_texel(__global const float *pyramid, int w, int row, int wk, int hk, int x,
                            int y)
{
  x = ((x % wk) + wk) % wk;
  y = clamp(y, 0, hk - 1);
  return vload3(0, pyramid + 4 * ((row + y) * w + x));
}

/* Level k (its first row `row`) bilinear at map coordinates (s, t) ∈ [0, 1]², wrapping in s
 * as env_lookup. */
inline float3 pyramid_bilinear(__global const float *pyramid, int w, int h, int k, int row,
                               float s, float t)
{
  int wk = max(w >> k, 1), hk = max(h >> k, 1);
  float fx = s * wk - 0.5f, fy = clamp(t * hk - 0.5f, 0.0f, (float)(hk - 1));
  int x0 = (int)floor(fx), y0 = (int)floor(fy);
  float ax = fx - x0, ay = fy - y0;
  return (pyramid_texel(pyramid, w, row, wk, hk, x0, y0) * (1.0f - ax) +
          pyramid_texel(pyramid, w, row, wk, hk, x0 + 1, y0) * ax) *
             (1.0f - ay) +
         (pyramid_texel(pyramid, w, row, wk, hk, x0, y0 + 1) * (1.0f - ax) +
          pyramid_texel(pyramid, w, row, wk, hk, x0 + 1, y0 + 1) * ax) *
             ay;
}

/* The World along world direction d averaged over `solid_angle` steradians around it. */
inline float3 world_filtered(__global const float *pyramid, int w, int h, int levels,
                             float rotation, float3 d, float solid_angle)
{
  float3 m = normalize(env_map_vector(d, rotation));
  float s = env_map_s(m), z = clamp(m.z, -1.0f, 1.0f);
  float t = acos(z) / M_PI_F;
  float sin_t = fmax(sqrt(fmax(1.0f - z * z, 0.0f)), 0.5f / (float)h);
  float texel = (2.0f * M_PI_F / w) * (M_PI_F / h) * sin_t;
  float lod = 0.5f * log2(fmax(solid_angle / texel, 1e-30f)) + (float)LOBE_LOD_BIAS;
  lod = clamp(lod, 0.0f, (float)(levels - 1));
  int k0 = min((int)floor(lod), levels - 1), k1 = min(k0 + 1, levels - 1);
  float f = lod - k0;
  int row0 = pyramid_row(h, k0), row1 = row0 + (k1 > k0 ? max(h >> k0, 1) : 0);
  return pyramid_bilinear(pyramid, w, h, k0, row0, s, t) * (1.0f - f) +
         pyramid_bilinear(pyramid, w, h, k1, row1, s, t) * f;
}

/* The unshadowed light leaving analytic surface point sp towards sp->wo, times its exposure:
 * the World through its pyramid (frame `frame`'s directions) and Blender's lights as the
 * viewport lights them (their deterministic points, no shadows). The World's terms evaluate
 * the codec in the point's own frame, without the mapping's blend: an analytic codec is the
 * same in every frame about the normal (its angles are unused). */
inline float3 lobe_light(__global const float *I, __global const float *F, const SurfacePoint *sp,
                         __global const float *pyramid, int w, int h, int levels,
                         float rotation, __global const float *scene_lights,
                         int scene_light_count, float eps, __global const float *bounds,
                         __global const int *links, __global const float *corners, uint frame,
                         int samples)
{
  float3 sum = (float3)(0.0f);
  samples = max(samples, 1);
  for (int k = 0; k < samples; k++) {
    float3 r = lobe_point(frame * (uint)samples + (uint)k);
    float pdf;
    float3 wi = bsdf_sample_at(I, F, 0, sp->wo, r.x, (float2)(r.y, r.z), &pdf);
    if (!(pdf > 0.0f) || wi.z <= 0.0f) {
      continue;
    }
    float3 dir = wi.x * sp->t + wi.y * sp->b + wi.z * sp->n;
    float3 light = world_filtered(pyramid, w, h, levels, rotation, dir,
                                  1.0f / ((float)samples * pdf));
    sum += btf_evaluate(I, F, sp->btf_uv, wi, sp->wo, 0.0f, 0.0f, 0.0f, 0.0f) * light / pdf;
  }
  sum /= (float)samples;
  /* The suns, taken out of the pyramid: directional lights, exactly (their row follows the
   * levels; directions in the map's frame, turned back by the World's rotation). */
  __global const float *suns = pyramid + 4 * pyramid_row(h, levels) * w;
  int sun_count = (int)suns[3];
  float2 cs = env_rotation(rotation);
  for (int i = 0; i < sun_count; i++) {
    float3 m = vload3(0, suns + 8 * i), power = vload3(0, suns + 8 * i + 4);
    float3 dir = (float3)(cs.x * m.x + cs.y * m.y, cs.x * m.y - cs.y * m.x, m.z);
    float3 wi = to_frame(sp, dir);
    if (wi.z > 0.0f) {
      sum += btf_evaluate(I, F, sp->btf_uv, wi, sp->wo, 0.0f, 0.0f, 0.0f, 0.0f) * power;
    }
  }
  sum += blender_lights(sp, I, F, scene_lights, scene_light_count, eps, bounds, links, corners,
                        0);
  return sum * sp->exposure;
}

#endif
