/* Blender's lights at a surface point (layout and units: btf_addon/scene/lights.py).
 *
 * Every light is reduced to samples "direction, distance, factor E" with the contribution
 * value(wi) · E, value being the BTF's (apparent BRDF × cos θi). Deterministic mode (smp == 0)
 * lights from fixed points: a point light's centre, an AREA_GRID × AREA_GRID grid of cell
 * centres on an area light; the sampled mode draws one random point per light and sample. */
#ifndef BTF_LIGHTS_H
#define BTF_LIGHTS_H

#include "btf_random.h"

#define LIGHT_FLOATS 20
#define TYPE_SUN 0
#define TYPE_POINT 1
#define TYPE_AREA 2
#define AREA_GRID 4

/* Light-type variants (btf_addon/scene/analysis.py): only the types the scene has are
 * compiled; undefined means all. Point covers spot lights (a spot is a point with a cone). */
#ifndef HAS_AREA_LIGHTS
#define HAS_AREA_LIGHTS 1
#endif
#ifndef HAS_SUN_LIGHTS
#define HAS_SUN_LIGHTS 1
#endif
#ifndef HAS_POINT_LIGHTS
#define HAS_POINT_LIGHTS 1
#endif

/* The light's sample for the square's point u ∈ [0, 1)²; returns E (0: no light this way). */
inline float3 light_sample(__global const float *L, float3 p, float2 u, bool jitter, float3 *dir,
                           float *dist)
{
  int type = (int)L[3];
  float3 rgb = vload3(0, L + 4 * 1);
#if HAS_SUN_LIGHTS
  if (type == TYPE_SUN) {
    *dir = vload3(0, L);
    *dist = INFINITY;
    return rgb;
  }
#endif
  float3 centre = vload3(0, L);
#if HAS_AREA_LIGHTS
  if (type == TYPE_AREA) {
    float3 hu = vload3(0, L + 4 * 3), hv = vload3(0, L + 4 * 4);
    float a = 2.0f * u.x - 1.0f, b = 2.0f * u.y - 1.0f;
    float area = 4.0f * length(cross(hu, hv));
    if (L[19] > 0.5f) { /* ellipse: the square mapped onto the disc, area-preserving */
      float r = sqrt(u.x), phi = 2.0f * M_PI_F * u.y;
      a = r * cos(phi);
      b = r * sin(phi);
      area *= 0.25f * M_PI_F;
    }
    float3 d = centre + a * hu + b * hv - p;
    float len = length(d);
    *dist = len;
    *dir = d / fmax(len, 1e-30f);
    float cos_light = -dot(*dir, vload3(0, L + 4 * 2));
    return cos_light > 0.0f ? rgb * (cos_light * area / fmax(len * len, 1e-12f)) : (float3)(0.0f);
  }
#endif
#if !HAS_POINT_LIGHTS
  *dir = (float3)(0.0f, 0.0f, 1.0f); /* not reached: the scene has no point or spot light */
  *dist = 0.0f;
  return (float3)(0.0f);
#else
  float3 target = centre;
  float radius = L[7];
  if (jitter && radius > 0.0f) { /* a disc of the light's radius facing the point */
    float3 w = normalize(p - centre);
    float3 t = normalize(cross(fabs(w.z) < 0.9f ? (float3)(0, 0, 1) : (float3)(1, 0, 0), w));
    float r = radius * sqrt(u.x), phi = 2.0f * M_PI_F * u.y;
    target += r * cos(phi) * t + r * sin(phi) * cross(w, t);
  }
  float3 d = target - p;
  float len = length(d);
  *dist = len;
  *dir = d / fmax(len, 1e-30f);
  float mask = 1.0f;
  float cos_half = L[11];
  if (cos_half > -1.0f) { /* a spot: Cycles' smoothstep across the blend */
    float cos_gamma = -dot(*dir, vload3(0, L + 4 * 2));
    float smooth = L[15];
    if (smooth <= 0.0f) {
      mask = cos_gamma > cos_half ? 1.0f : 0.0f;
    }
    else {
      float x = clamp((cos_gamma - cos_half) * smooth, 0.0f, 1.0f);
      mask = x * x * (3.0f - 2.0f * x);
    }
  }
  return rgb * (mask / fmax(len * len, 1e-12f));
#endif
}

/* All Blender lights at a surface point; smp == 0 → deterministic points. Delta and area
 * lights cannot be hit by sampled directions (they are not geometry), so they take no part
 * in MIS. */
inline float3 blender_lights(const SurfacePoint *sp, Stream I, Stream F,
                             __global const float *lights, int count, float eps,
                             __global const float *bounds, __global const int *links,
                             __global const float *corners, Sampler *smp)
{
  float3 sum = (float3)(0.0f);
  for (int i = 0; i < count; i++) {
    __global const float *L = lights + LIGHT_FLOATS * i;
    int n = (!smp && (int)L[3] == TYPE_AREA) ? AREA_GRID * AREA_GRID : 1;
    for (int k = 0; k < n; k++) {
      float2 u = smp ? next_2d(smp)
                     : (float2)(((k % AREA_GRID) + 0.5f) / AREA_GRID,
                                ((k / AREA_GRID) + 0.5f) / AREA_GRID);
      float3 dir;
      float dist;
      float3 e = light_sample(L, sp->start, u, smp != 0, &dir, &dist);
      float3 wi = to_frame(sp, dir);
      if (wi.z <= 0.0f || !(e.x + e.y + e.z > 0.0f)) {
        continue;
      }
#if HAS_SHADOWS
      float tmax = isinf(dist) ? INFINITY : dist * (1.0f - 1e-4f);
      if (!unoccluded(sp->start, dir, eps, tmax, bounds, links, corners)) {
        continue;
      }
#endif
      sum += btf_mapped(I, F, sp, wi) * e / (float)n;
    }
  }
  return sum;
}

#endif
