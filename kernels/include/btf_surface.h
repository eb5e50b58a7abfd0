/* What both final-render kernels compute for a pixel before lighting: the camera ray and, at
 * its nearest hit, the shading frame (layout of corners: btf_addon/scene/scene.py). */
#ifndef BTF_SURFACE_H
#define BTF_SURFACE_H

typedef struct {
  float3 p;     /* hit point */
  float3 start; /* shadow-ray origin: lifted onto the smooth surface, offset along n */
  float3 n, t, b; /* shading frame (n faces the viewer) */
  float3 wo;    /* view direction in the frame */
  float2 uv;    /* mesh UV */
  float2 btf_uv; /* after the material's UV transform */
  float2 view;  /* wo as (theta, phi) degrees */
  int material;
} SurfacePoint;

/* Raster position (x, y) in pixels (row 0 at the top, (x + ½, y + ½) the centre of pixel
 * (x, y)) → ray through it, from the near plane. Anti-aliasing moves the position inside the
 * pixel filter's footprint (include/btf_filter.h); the centre gives the images of before. */
inline void camera_ray_at(float2 raster, int width, int height,
                          __global const float *world_from_clip, float3 *o, float3 *d)
{
  float2 ndc = (float2)(raster.x / width * 2.0f - 1.0f, 1.0f - raster.y / height * 2.0f);
  float4 m0 = vload4(0, world_from_clip), m1 = vload4(1, world_from_clip);
  float4 m2 = vload4(2, world_from_clip), m3 = vload4(3, world_from_clip); /* rows */
  float4 pn = (float4)(ndc, -1.0f, 1.0f), pf = (float4)(ndc, 1.0f, 1.0f);
  float4 near_h = (float4)(dot(m0, pn), dot(m1, pn), dot(m2, pn), dot(m3, pn));
  float4 far_h = (float4)(dot(m0, pf), dot(m1, pf), dot(m2, pf), dot(m3, pf));
  *o = near_h.xyz / near_h.w;
  *d = normalize(far_h.xyz / far_h.w - *o);
}

/* The ray through raster position ``raster`` and its nearest triangle (-1 where only the World
 * is seen). */
inline int primary_hit_at(float2 raster, int width, int height,
                          __global const float *world_from_clip, int tri_count,
                          __global const float *bounds, __global const int *links,
                          __global const float *corners, float3 *o, float3 *d, float *t, float *bu,
                          float *bv)
{
  camera_ray_at(raster, width, height, world_from_clip, o, d);
  *t = *bu = *bv = 0.0f;
  return tri_count > 0 ? trace(*o, *d, 0.0f, INFINITY, bounds, links, corners, false, t, bu, bv)
                       : -1;
}

/* The same through the centre of pixel (x, y). */
inline int primary_hit(int x, int y, int width, int height, __global const float *world_from_clip,
                       int tri_count, __global const float *bounds, __global const int *links,
                       __global const float *corners, float3 *o, float3 *d, float *t, float *bu,
                       float *bv)
{
  return primary_hit_at((float2)(x + 0.5f, y + 0.5f), width, height, world_from_clip, tri_count,
                        bounds, links, corners, o, d, t, bu, bv);
}

inline SurfacePoint surface_point(float3 o, float3 d, float t, float bu, float bv, int tri,
                                  __global const float *corners, __global const int *tri_material,
                                  __global const float *material_params, float eps)
{
  SurfacePoint sp;
  /* Corner k at c + 12k: position [0, 3), normal [3, 6), uv [6, 8), tangent + sign [8, 12). */
  __global const float *c = corners + 36 * tri;
  float w0 = 1.0f - bu - bv;
  sp.p = o + t * d;
  /* Shadow rays start from the point lifted onto the surface that the smooth normals describe
   * (Hanika 2021, "Hacking the shadow terminator"): on tessellated smooth meshes this stops
   * faces from shadowing their neighbours near the terminator. */
  float3 lifted = (float3)(0.0f);
  for (int k = 0; k < 3; k++) {
    float3 pk = vload3(0, c + 12 * k), nk = normalize(vload3(0, c + 12 * k + 3));
    float3 tmp = sp.p - pk;
    tmp -= fmin(dot(tmp, nk), 0.0f) * nk;
    lifted += (k == 0 ? w0 : (k == 1 ? bu : bv)) * (pk + tmp);
  }
  float3 n = normalize(w0 * vload3(0, c + 3) + bu * vload3(0, c + 15) + bv * vload3(0, c + 27));
  sp.uv = w0 * vload2(0, c + 6) + bu * vload2(0, c + 18) + bv * vload2(0, c + 30);
  float4 tg = w0 * vload4(0, c + 8) + bu * vload4(0, c + 20) + bv * vload4(0, c + 32);
  float3 wo_world = -d;
  float side = dot(n, wo_world) < 0.0f ? -1.0f : 1.0f; /* back faces shaded as seen */
  n *= side;
  float3 tt = tg.xyz - n * dot(n, tg.xyz);
  float tl = length(tt);
  tt = tl > 1e-8f ? tt / tl
                  : normalize(cross(fabs(n.z) < 0.9f ? (float3)(0, 0, 1) : (float3)(1, 0, 0), n));
  sp.n = n;
  sp.t = tt;
  sp.b = cross(n, tt) * (c[11] < 0.0f ? -1.0f : 1.0f) * side;
  sp.wo = (float3)(dot(wo_world, tt), dot(wo_world, sp.b), dot(wo_world, n));
  sp.view = btf_theta_phi_deg(sp.wo);
  sp.start = (side > 0.0f ? lifted : sp.p) + n * eps; /* lifting assumes the outer side */
  sp.material = tri_material[tri];
  __global const float *mp = material_params + 8 * sp.material;
  sp.btf_uv = (float2)(mp[0] * sp.uv.x + mp[2] * sp.uv.y, mp[1] * sp.uv.x + mp[3] * sp.uv.y);
  return sp;
}

inline float3 to_frame(const SurfacePoint *sp, float3 d)
{
  return (float3)(dot(d, sp->t), dot(d, sp->b), dot(d, sp->n));
}

#endif
