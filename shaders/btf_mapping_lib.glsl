/* The material's mapping at a fragment (btf_addon/core/mapping.py map_points and
 * mapped_evaluate; kernels/include/btf_surface.h map_point and btf_mapped do the same).
 * Needs the sampler material_blocks (MATERIAL_BLOCK_FLOATS floats per mesh, slots M_* from
 * btf_addon/core/codecs/packed.py, laid out TABLE_WIDTH floats a row as the BTF tables are) and the
 * varying v_block (this fragment's mesh's block index, the same at its triangle's corners). */

float mblock(int i)
{
  int k = int(v_block + 0.5) * MATERIAL_BLOCK_FLOATS + i;
  return texelFetch(material_blocks, ivec2(k % TABLE_WIDTH, k / TABLE_WIDTH), 0).r;
}

/* Up to 3 projections: texture coordinates, tangent frame (with the shading normal), weight. */
int map_count;
int map_filter;
vec2 map_uv[3];
vec3 map_t[3];
vec3 map_b[3];
float map_w[3];

void box_frame(vec3 n, vec3 along_u, vec3 along_v, out vec3 t, out vec3 b)
{
  vec3 tt = along_u - n * dot(n, along_u);
  float tl = length(tt);
  tt = tl > 1e-8 ? tt / tl : normalize(cross(abs(n.z) < 0.9 ? vec3(0, 0, 1) : vec3(1, 0, 0), n));
  vec3 bb = cross(n, tt);
  t = tt;
  b = dot(bb, along_v) < 0.0 ? -bb : bb;
}

/* p: world position; n: unit shading normal; (t, b): the mesh's tangent frame; uv: mesh UV. */
void map_point(vec3 p, vec3 n, vec3 t, vec3 b, vec2 uv)
{
  vec2 a0 = vec2(mblock(M_UV_MATRIX), mblock(M_UV_MATRIX + 1)); /* rows of A */
  vec2 a1 = vec2(mblock(M_UV_MATRIX + 2), mblock(M_UV_MATRIX + 3));
  vec2 c = vec2(mblock(M_UV_OFFSET), mblock(M_UV_OFFSET + 1));
  map_filter = int(mblock(M_TEXEL_FILTER) + 0.5);
  if (int(mblock(M_MAPPING) + 0.5) != MAPPING_BOX) {
    map_count = 1;
    map_uv[0] = vec2(dot(a0, uv), dot(a1, uv)) + c;
    map_t[0] = t;
    map_b[0] = b;
    map_w[0] = 1.0;
    return;
  }
  int bx = M_BOX_FROM_WORLD; /* 3×4 rows */
  vec3 r0 = vec3(mblock(bx), mblock(bx + 1), mblock(bx + 2));
  vec3 r1 = vec3(mblock(bx + 4), mblock(bx + 5), mblock(bx + 6));
  vec3 r2 = vec3(mblock(bx + 8), mblock(bx + 9), mblock(bx + 10));
  vec3 q = vec3(dot(r0, p) + mblock(bx + 3), dot(r1, p) + mblock(bx + 7),
                dot(r2, p) + mblock(bx + 11));
  vec3 m = normalize(vec3(dot(r0, n), dot(r1, n), dot(r2, n)));
  vec3 am = abs(m);
  float mx = max(am.x, max(am.y, am.z));
  float blend = mblock(M_BOX_BLEND);
  vec3 w;
  if (blend > 0.0) {
    w = clamp((am - mx) / blend + 1.0, 0.0, 1.0);
  }
  else {
    int k = (am.x >= am.y && am.x >= am.z) ? 0 : (am.y >= am.z ? 1 : 2);
    w = vec3(k == 0 ? 1.0 : 0.0, k == 1 ? 1.0 : 0.0, k == 2 ? 1.0 : 0.0);
  }
  w /= w.x + w.y + w.z;
  vec3 sg = vec3(m.x >= 0.0 ? 1.0 : -1.0, m.y >= 0.0 ? 1.0 : -1.0, m.z >= 0.0 ? 1.0 : -1.0);
  /* box-frame axes in world space: rows of the (scaled orthonormal) 3×3 part, whose transpose
   * maps box directions to world */
  vec3 ex = r0, ey = r1, ez = r2;
  vec2 s0 = vec2(sg.x * q.y, q.z), s1 = vec2(-sg.y * q.x, q.z), s2 = vec2(sg.z * q.x, q.y);
  map_count = 3;
  map_uv[0] = vec2(dot(a0, s0), dot(a1, s0)) + c;
  map_uv[1] = vec2(dot(a0, s1), dot(a1, s1)) + c;
  map_uv[2] = vec2(dot(a0, s2), dot(a1, s2)) + c;
  box_frame(n, sg.x * ey, ez, map_t[0], map_b[0]);
  box_frame(n, -sg.y * ex, ez, map_t[1], map_b[1]);
  box_frame(n, sg.z * ex, ey, map_t[2], map_b[2]);
  map_w[0] = w.x;
  map_w[1] = w.y;
  map_w[2] = w.z;
}

/* The BTF value for world directions wi (light) and wo (view), exposure not applied. */
vec3 btf_mapped(vec3 n, vec3 wi_world, vec3 wo_world)
{
  vec3 sum = vec3(0.0);
  for (int k = 0; k < map_count; k++) {
    if (map_w[k] > 0.0) {
      vec3 wi = to_tangent(wi_world, map_t[k], map_b[k], n);
      vec3 wo = to_tangent(wo_world, map_t[k], map_b[k], n);
      sum += map_w[k] * btf_filtered(map_filter, map_uv[k], theta_phi_deg(wi), theta_phi_deg(wo));
    }
  }
  return sum;
}
