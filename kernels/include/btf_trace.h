/* Ray–triangle and BVH traversal (layout: btf_addon/scene/bvh.py). */
#ifndef BTF_TRACE_H
#define BTF_TRACE_H

#define BVH_STACK 64

/* Möller–Trumbore; returns t in (tmin, tmax) or INFINITY. Degenerate triangles never hit. */
inline float intersect_triangle(float3 o, float3 d, float3 v0, float3 v1, float3 v2, float tmin,
                                float tmax, float *bu, float *bv)
{
  float3 e1 = v1 - v0, e2 = v2 - v0;
  float3 p = cross(d, e2);
  float det = dot(e1, p);
  if (fabs(det) < 1e-20f) {
    return INFINITY;
  }
  float inv = 1.0f / det;
  float3 s = o - v0;
  float u = dot(s, p) * inv;
  if (u < 0.0f || u > 1.0f) {
    return INFINITY;
  }
  float3 q = cross(s, e1);
  float v = dot(d, q) * inv;
  if (v < 0.0f || u + v > 1.0f) {
    return INFINITY;
  }
  float t = dot(e2, q) * inv;
  if (!(t > tmin && t < tmax)) { /* also rejects NaN */
    return INFINITY;
  }
  *bu = u;
  *bv = v;
  return t;
}

/* The slab test's min and max as plain comparisons: one vminps/vmaxps each. OpenCL's fmin and
 * fmax must return the number where one operand is NaN, which PoCL compiles to a compare and a
 * blend around every one of them: the box test was most of trace(), itself a quarter of a demo
 * sample; these took 17 % off the demo's samples and 16 % off the Lambertian sphere's. No NaN
 * arises here from a finite ray: trace() keeps 1/d finite. A NaN ray meets no triangle
 * either way (intersect_triangle rejects a NaN t). */
#define FAST_MIN(a, b) ((a) < (b) ? (a) : (b))
#define FAST_MAX(a, b) ((a) > (b) ? (a) : (b))
inline bool intersect_box(float3 o, float3 inv_d, __global const float *b, float tmax)
{
  float3 t0 = ((float3)(b[0], b[1], b[2]) - o) * inv_d;
  float3 t1 = ((float3)(b[3], b[4], b[5]) - o) * inv_d;
  float3 lo = FAST_MIN(t0, t1), hi = FAST_MAX(t0, t1);
  float enter = FAST_MAX(FAST_MAX(lo.x, lo.y), FAST_MAX(lo.z, 0.0f));
  float leave = FAST_MIN(FAST_MIN(hi.x, hi.y), FAST_MIN(hi.z, tmax));
  return enter <= leave;
}

/* Corner layout: 12 floats per corner (position, normal, uv, tangent xyz, bitangent sign),
 * 3 corners per triangle. Returns the triangle hit (or -1); any_hit stops at the first. */
inline int trace(float3 o, float3 d, float tmin, float tmax, __global const float *bounds,
                 __global const int *links, __global const float *corners, bool any_hit,
                 float *t_hit, float *u_hit, float *v_hit)
{
  /* an axis-parallel ray's 1/d is ±1e30, not ±inf: a ray starting on a slab's plane would
   * otherwise make 0 · inf = NaN there */
  float3 tiny = (float3)(1e-30f);
  float3 inv_d = 1.0f / select(d, copysign(tiny, d), isless(fabs(d), tiny));
  int stack[BVH_STACK];
  int top = 0;
  stack[top++] = 0;
  int hit = -1;
  float best = tmax;
  while (top > 0) {
    int node = stack[--top];
    if (!intersect_box(o, inv_d, bounds + 6 * node, best)) {
      continue;
    }
    int a = links[2 * node], count = links[2 * node + 1];
    if (count > 0) {
      for (int i = a; i < a + count; i++) {
        __global const float *c = corners + 36 * i;
        float bu, bv;
        float t = intersect_triangle(o, d, vload3(0, c), vload3(0, c + 12), vload3(0, c + 24),
                                     tmin, best, &bu, &bv);
        if (t < best) {
          best = t;
          hit = i;
          *t_hit = t;
          *u_hit = bu;
          *v_hit = bv;
          if (any_hit) {
            return hit;
          }
        }
      }
    }
    else if (top + 2 <= BVH_STACK) {
      stack[top++] = a;        /* right child */
      stack[top++] = node + 1; /* left child, visited first */
    }
  }
  return hit;
}

/* Whether nothing lies between start and start + t·dir for t in (eps, tmax): a shadow ray. */
inline bool unoccluded(float3 start, float3 dir, float eps, float tmax,
                       __global const float *bounds, __global const int *links,
                       __global const float *corners)
{
  float t, u, v;
  return trace(start, dir, eps, tmax, bounds, links, corners, true, &t, &u, &v) < 0;
}

#endif
