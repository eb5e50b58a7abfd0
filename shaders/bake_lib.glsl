/* The light bake's playback in the drawer: kernels/include/btf_bake.h line for line (its rules
 * are documented in btf_addon/scene/bake_points.py, whose numpy ``playback`` both are tested
 * against), reading the bake from two textures (btf_addon/render/bake_playback.py packs them):
 *
 * bake_index: an R32F stream laid out TABLE_WIDTH texels a row, as the BTF tables:
 *   [0] view bins V, [1] where tri_points start, then per bake triangle t its cuts n at
 *   2 + 2t and its first entry at 3 + 2t, then tri_points (integers, exact below 2^24);
 * bake_values: RGBA32F, TABLE_WIDTH texels a row, texel point·(V² + 1) + bin holding its light
 *   per unit response (rgb), texel point·(V² + 1) + V² its light's direction (xyz, the frame's;
 *   bake_points.pack_values).
 *
 * BAKE_BIN_MARGIN (bake_points.BIN_MARGIN) arrives as a define (btf_addon/gl/interface.py).
 * Nothing here reads a BTF: the response the value is per unit of is surface_frag.glsl's. */

#ifndef BAKE_BIN_MARGIN
#error BAKE_BIN_MARGIN missing: build through btf_addon/gl/interface.py
#endif

int bake_int(int i)
{
  return int(texelFetch(bake_index, ivec2(i % TABLE_WIDTH, i / TABLE_WIDTH), 0).r + 0.5);
}

vec3 bake_value(int i)
{
  return texelFetch(bake_values, ivec2(i % TABLE_WIDTH, i / TABLE_WIDTH), 0).rgb;
}

/* The view direction's point on the concentric square (as bake_square in btf_bake.h). */
vec2 bake_square(vec3 w)
{
  float xy = sqrt(w.x * w.x + w.y * w.y);
  w = vec3(w.x, w.y, w.z > 0.0 ? w.z : 1e-6 * xy); /* grazing or below: just above */
  w /= max(length(w), 1e-30);
  float r = sqrt(w.x * w.x + w.y * w.y), a, b;
  if (abs(w.x) > abs(w.y)) {
    a = sign(w.x) * r;
    b = a * (4.0 / 3.14159265358979) * atan(w.y * sign(w.x), abs(w.x));
  }
  else {
    b = sign(w.y) * r;
    a = b == 0.0 ? 0.0 : b * (4.0 / 3.14159265358979) * atan(w.x * sign(w.y), abs(w.y));
  }
  return clamp(vec2(a + 1.0, b + 1.0) * 0.5, 0.0, 1.0);
}

/* A blend of unit light directions made one again (bake_direction in btf_bake.h). */
vec3 bake_direction(vec3 sum)
{
  float len = length(sum);
  return len > 1e-6 && !isinf(len) && !isnan(len) ? sum / len : vec3(0.0, 0.0, 1.0);
}

/* The bake's light per unit response at bake triangle `tri`, barycentrics `bary` (of corners
 * 1 and 2), for the view `wo` in the surface's frame: 3 grid points × 4 view bins;
 * `light_dir`: the points' light direction blended (the frame's). */
vec3 bake_lookup(int tri, vec2 bary, vec3 wo, out vec3 light_dir)
{
  int view_bins = bake_int(0), points_at = bake_int(1);
  int n = max(bake_int(2 + 2 * tri), 1), first = bake_int(3 + 2 * tri);
  float a = bary.x * float(n), b = bary.y * float(n);
  if (isnan(a) || isinf(a) || isnan(b) || isinf(b)) {
    a = b = 0.0;
  }
  int i = clamp(int(floor(a)), 0, n - 1);
  int j = clamp(int(floor(b)), 0, n - 1 - i);
  float fa = a - float(i), fb = b - float(j);
  ivec3 vi, vj;
  vec3 w;
  /* the lower cell also where no upper one exists (past the far edge by rounding) */
  if (fa + fb <= 1.0 || i + j >= n - 1) {
    vi = ivec3(i, i + 1, i);
    vj = ivec3(j, j, j + 1);
    w = vec3(1.0 - fa - fb, fa, fb);
  }
  else {
    vi = ivec3(i + 1, i, i + 1);
    vj = ivec3(j + 1, j + 1, j);
    w = vec3(fa + fb - 1.0, 1.0 - fa, 1.0 - fb);
  }
  w = max(w, vec3(0.0)); /* outside the cell by rounding on its edges */
  float total = w.x + w.y + w.z;
  vec2 s = (bake_square(wo) - BAKE_BIN_MARGIN) / (1.0 - 2.0 * BAKE_BIN_MARGIN) *
           float(view_bins - 1);
  s = clamp(s, 0.0, float(view_bins - 1));
  int c0 = min(int(floor(s.x)), max(view_bins - 2, 0));
  int r0 = min(int(floor(s.y)), max(view_bins - 2, 0));
  float fx = s.x - float(c0), fy = s.y - float(r0);
  int c1 = min(c0 + 1, view_bins - 1), r1 = min(r0 + 1, view_bins - 1);
  int bins = view_bins * view_bins;
  vec3 sum = vec3(0.0), dir = vec3(0.0);
  for (int k = 0; k < 3; k++) {
    int point = bake_int(points_at + first + vi[k] * (n + 1) - vi[k] * (vi[k] - 1) / 2 + vj[k]);
    int row = (bins + 1) * point;
    dir += w[k] * bake_value(row + bins);
    vec3 v = (bake_value(row + r0 * view_bins + c0) * (1.0 - fx) +
              bake_value(row + r0 * view_bins + c1) * fx) *
                 (1.0 - fy) +
             (bake_value(row + r1 * view_bins + c0) * (1.0 - fx) +
              bake_value(row + r1 * view_bins + c1) * fx) *
                 fy;
    sum += w[k] * v;
  }
  light_dir = bake_direction(dir);
  return total > 0.0 ? sum / total : sum;
}
