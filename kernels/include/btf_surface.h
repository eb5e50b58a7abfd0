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
  float2 btf_uv; /* texture coordinates of the first (UV: only) projection */
  int material; /* index of the material's packed tables */
  /* The material's mapping (btf_addon/core/mapping.py map_points): up to 3 projections, each
   * with texture coordinates, a tangent frame (t, b with the shading normal n) and a weight. */
  int map_count;
  int texel_filter;
  float exposure; /* the multiplier 2^stops */
  float2 map_uv[3];
  float3 map_t[3], map_b[3];
  float map_w[3];
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

/* Box projection's tangent along `along_u` in the plane of n, bitangent towards `along_v`
 * (core/mapping.py _frame_from). */
inline void box_frame(float3 n, float3 along_u, float3 along_v, float3 *t, float3 *b)
{
  float3 tt = along_u - n * dot(n, along_u);
  float tl = length(tt);
  tt = tl > 1e-8f ? tt / tl
                  : normalize(cross(fabs(n.z) < 0.9f ? (float3)(0, 0, 1) : (float3)(1, 0, 0), n));
  float3 bb = cross(n, tt);
  *t = tt;
  *b = dot(bb, along_v) < 0.0f ? -bb : bb;
}

/* The material block's mapping at a surface point (block: MATERIAL_BLOCK_FLOATS floats, slots
 * M_* from btf_addon/core/codecs/packed.py). Needs sp->p, n, t, b, uv. */
inline void map_point(SurfacePoint *sp, __global const float *mb)
{
  float2 a0 = (float2)(mb[M_UV_MATRIX], mb[M_UV_MATRIX + 1]); /* rows of A */
  float2 a1 = (float2)(mb[M_UV_MATRIX + 2], mb[M_UV_MATRIX + 3]);
  float2 c = (float2)(mb[M_UV_OFFSET], mb[M_UV_OFFSET + 1]);
  sp->texel_filter = (int)mb[M_TEXEL_FILTER];
  sp->exposure = mb[M_EXPOSURE];
  if ((int)mb[M_MAPPING] != MAPPING_BOX) {
    sp->map_count = 1;
    sp->map_uv[0] = (float2)(dot(a0, sp->uv), dot(a1, sp->uv)) + c;
    sp->map_t[0] = sp->t;
    sp->map_b[0] = sp->b;
    sp->map_w[0] = 1.0f;
    sp->btf_uv = sp->map_uv[0];
    return;
  }
  __global const float *bx = mb + M_BOX_FROM_WORLD; /* 3×4 rows */
  float3 r0 = vload3(0, bx), r1 = vload3(0, bx + 4), r2 = vload3(0, bx + 8);
  float3 q = (float3)(dot(r0, sp->p) + bx[3], dot(r1, sp->p) + bx[7], dot(r2, sp->p) + bx[11]);
  float3 m = normalize((float3)(dot(r0, sp->n), dot(r1, sp->n), dot(r2, sp->n)));
  float3 am = fabs(m);
  float mx = fmax(am.x, fmax(am.y, am.z));
  float blend = mb[M_BOX_BLEND];
  float3 w;
  if (blend > 0.0f) {
    w = clamp((am - mx) / blend + 1.0f, 0.0f, 1.0f);
  }
  else {
    int k = (am.x >= am.y && am.x >= am.z) ? 0 : (am.y >= am.z ? 1 : 2);
    w = (float3)(k == 0 ? 1.0f : 0.0f, k == 1 ? 1.0f : 0.0f, k == 2 ? 1.0f : 0.0f);
  }
  w /= w.x + w.y + w.z;
  float3 sg = (float3)(m.x >= 0.0f ? 1.0f : -1.0f, m.y >= 0.0f ? 1.0f : -1.0f,
                       m.z >= 0.0f ? 1.0f : -1.0f);
  /* box-frame axes in world space: rows of the (scaled orthonormal) 3×3 part, whose transpose
   * maps box directions to world */
  float3 ex = r0, ey = r1, ez = r2;
  float2 s[3] = {(float2)(sg.x * q.y, q.z), (float2)(-sg.y * q.x, q.z), (float2)(sg.z * q.x, q.y)};
  float3 along_u[3] = {sg.x * ey, -sg.y * ex, sg.z * ex};
  float3 along_v[3] = {ez, ez, ey};
  float wk[3] = {w.x, w.y, w.z};
  sp->map_count = 3;
  for (int k = 0; k < 3; k++) {
    sp->map_uv[k] = (float2)(dot(a0, s[k]), dot(a1, s[k])) + c;
    box_frame(sp->n, along_u[k], along_v[k], &sp->map_t[k], &sp->map_b[k]);
    sp->map_w[k] = wk[k];
  }
  sp->btf_uv = sp->map_uv[0];
}

/* The BTF value at a mapped point for wi in the point's frame (t, b, n), exposure not applied:
 * per projection, wi and wo re-expressed in its frame and the filtered lookup, weighted
 * (core/mapping.py mapped_evaluate). */
inline float3 btf_mapped(__global const float *I, __global const float *F,
                         const SurfacePoint *sp, float3 wi)
{
  if (sp->map_count == 1) {
    return btf_filtered(I, F, sp->texel_filter, sp->map_uv[0], wi, sp->wo);
  }
  float3 wi_world = wi.x * sp->t + wi.y * sp->b + wi.z * sp->n;
  float3 wo_world = sp->wo.x * sp->t + sp->wo.y * sp->b + sp->wo.z * sp->n;
  float3 sum = (float3)(0.0f);
  for (int k = 0; k < sp->map_count; k++) {
    if (sp->map_w[k] > 0.0f) {
      float3 wik = (float3)(dot(wi_world, sp->map_t[k]), dot(wi_world, sp->map_b[k]), wi.z);
      float3 wok = (float3)(dot(wo_world, sp->map_t[k]), dot(wo_world, sp->map_b[k]), sp->wo.z);
      sum += sp->map_w[k] * btf_filtered(I, F, sp->texel_filter, sp->map_uv[k], wik, wok);
    }
  }
  return sum;
}

/* tri_block: per triangle, the row of its mesh's material block in `blocks`
 * (MATERIAL_BLOCK_FLOATS floats each; btf_addon/scene/scene.py Scene.material_blocks). */
inline SurfacePoint surface_point(float3 o, float3 d, float t, float bu, float bv, int tri,
                                  __global const float *corners, __global const int *tri_block,
                                  __global const float *blocks, float eps)
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
  sp.start = (side > 0.0f ? lifted : sp.p) + n * eps; /* lifting assumes the outer side */
  __global const float *mb = blocks + MATERIAL_BLOCK_FLOATS * tri_block[tri];
  sp.material = (int)mb[M_MATERIAL];
  map_point(&sp, mb);
  return sp;
}

inline float3 to_frame(const SurfacePoint *sp, float3 d)
{
  return (float3)(dot(d, sp->t), dot(d, sp->b), dot(d, sp->n));
}

#endif
