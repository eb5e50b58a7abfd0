/* An analytic material's unshadowed light from the World and Blender's lights, converged per
 * pixel: kernels/include/btf_lobe.h line for line (the method and the sequence are documented
 * there), with the analytic mixture's sampling of kernels/include/btf_sampling.h.
 *
 * world_pyramid: the World's pyramid (btf_addon/core/sampling/world_pyramid.py), RGBA32F,
 *   level 0's width, levels stacked top to bottom, then the suns' row;
 * world: x = the World's Z rotation (radians), y = the pyramid's levels, z = level 0's width,
 *   w = its height. LOBE_LOD_BIAS arrives as a define (gl/interface.py). */

#ifndef LOBE_LOD_BIAS
#error LOBE_LOD_BIAS missing: build through btf_addon/gl/interface.py
#endif

vec3 lobe_point(uint i)
{
  uvec3 x = uvec3(2147483648u) + i * uvec3(3518319155u, 2882110345u, 2360945575u);
  return vec3(x >> 8u) / 16777216.0;
}

/* The first row of level k (levels stacked top to bottom from level 0's height h). */
int pyramid_row(int h, int k)
{
  int row = 0;
  for (int j = 0; j < k; j++) {
    row += max(h >> j, 1);
  }
  return row;
}

vec3 pyramid_texel(int row, int wk, int hk, int x, int y)
{
  x = ((x % wk) + wk) % wk;
  y = clamp(y, 0, hk - 1);
  return texelFetch(world_pyramid, ivec2(x, row + y), 0).rgb;
}

/* Level k (its first row `row`) bilinear at map coordinates (s, t), wrapping in s. */
vec3 pyramid_bilinear(int w, int h, int k, int row, float s, float t)
{
  int wk = max(w >> k, 1), hk = max(h >> k, 1);
  float fx = s * float(wk) - 0.5, fy = clamp(t * float(hk) - 0.5, 0.0, float(hk - 1));
  int x0 = int(floor(fx)), y0 = int(floor(fy));
  float ax = fx - float(x0), ay = fy - float(y0);
  return (pyramid_texel(row, wk, hk, x0, y0) * (1.0 - ax) +
          pyramid_texel(row, wk, hk, x0 + 1, y0) * ax) *
             (1.0 - ay) +
         (pyramid_texel(row, wk, hk, x0, y0 + 1) * (1.0 - ax) +
          pyramid_texel(row, wk, hk, x0 + 1, y0 + 1) * ax) *
             ay;
}

vec3 world_filtered(vec3 d, float solid_angle)
{
  int w = int(world.z + 0.5), h = int(world.w + 0.5), levels = int(world.y + 0.5);
  float c = cos(world.x), sn = sin(world.x);
  vec3 m = normalize(vec3(c * d.x - sn * d.y, sn * d.x + c * d.y, d.z));
  float s = (3.14159265358979 - atan(m.y, m.x)) / 6.28318530717959;
  float z = clamp(m.z, -1.0, 1.0);
  float t = acos(z) / 3.14159265358979;
  float sin_t = max(sqrt(max(1.0 - z * z, 0.0)), 0.5 / float(h));
  float texel = (6.28318530717959 / float(w)) * (3.14159265358979 / float(h)) * sin_t;
  float lod = 0.5 * log2(max(solid_angle / texel, 1e-30)) + float(LOBE_LOD_BIAS);
  lod = clamp(lod, 0.0, float(levels - 1));
  int k0 = min(int(floor(lod)), levels - 1), k1 = min(k0 + 1, levels - 1);
  float f = lod - float(k0);
  int row0 = pyramid_row(h, k0), row1 = row0 + (k1 > k0 ? max(h >> k0, 1) : 0);
  return pyramid_bilinear(w, h, k0, row0, s, t) * (1.0 - f) +
         pyramid_bilinear(w, h, k1, row1, s, t) * f;
}

/* include/btf_sampling.h's analytic mixture: its GGX lobe's share, the visible normals' pdf
 * and sample, and the mixture's sample with its pdf. */
float ggx_lobe_probability()
{
  int codec = itab(H_CODEC);
  if (codec == CODEC_GGX) {
    return 0.9;
  }
  if (codec == CODEC_PRINCIPLED) {
    return 0.5 + 0.4 * ftab(F_METALLIC);
  }
  return 0.0;
}

float ggx_vndf_pdf(float alpha2, vec3 wi, vec3 wo)
{
  if (wi.z <= 0.0 || wo.z <= 0.0) {
    return 0.0;
  }
  vec3 m = normalize(wi + wo);
  float cos2 = m.z * m.z;
  float denom = 1.0 + (alpha2 - 1.0) * cos2;
  float d = alpha2 / (3.14159265358979 * denom * denom);
  float g1 = 1.0 / (1.0 + ggx_lambda(alpha2, wo.z));
  return g1 * d / (4.0 * wo.z);
}

vec3 ggx_vndf_sample(float alpha2, vec3 wo, vec2 u)
{
  float alpha = sqrt(alpha2);
  vec3 vh = normalize(vec3(alpha * wo.x, alpha * wo.y, wo.z));
  float len2 = vh.x * vh.x + vh.y * vh.y;
  vec3 t1 = len2 > 0.0 ? vec3(-vh.y, vh.x, 0.0) * inversesqrt(len2) : vec3(1.0, 0.0, 0.0);
  vec3 t2 = cross(vh, t1);
  float r = sqrt(u.x), phi = 6.28318530717959 * u.y;
  float p1 = r * cos(phi), p2 = r * sin(phi);
  float s = 0.5 * (1.0 + vh.z);
  p2 = (1.0 - s) * sqrt(max(1.0 - p1 * p1, 0.0)) + s * p2;
  vec3 nh = p1 * t1 + p2 * t2 + sqrt(max(1.0 - p1 * p1 - p2 * p2, 0.0)) * vh;
  vec3 m = normalize(vec3(alpha * nh.x, alpha * nh.y, max(nh.z, 1e-6)));
  return 2.0 * dot(wo, m) * m - wo;
}

vec3 mixture_sample(vec3 wo, float choice, vec2 u, out float pdf)
{
  float p = ggx_lobe_probability(), alpha2 = ftab(F_ALPHA2);
  vec3 d;
  if (choice < p) {
    d = ggx_vndf_sample(alpha2, wo, u);
  }
  else {
    float r = sqrt(u.x), phi = 6.28318530717959 * u.y;
    d = vec3(r * cos(phi), r * sin(phi), sqrt(max(1.0 - u.x, 0.0)));
  }
  float cosine = max(d.z, 0.0) / 3.14159265358979;
  pdf = p > 0.0 ? p * ggx_vndf_pdf(alpha2, d, wo) + (1.0 - p) * cosine : cosine;
  return d;
}

/* lobe_light of btf_lobe.h: the fragment's frame (t, b, n), its point p and view wo_world;
 * map_point ran first (Blender's lights read the mapping; the World's light needs none: an
 * analytic codec is the same in every frame about the normal, btf_eval_lib.glsl). */
vec3 lobe_light(vec3 p, vec3 t, vec3 b, vec3 n, vec3 wo_world, uint frame, int samples,
                int blender_lights)
{
  vec3 wo = to_tangent(wo_world, t, b, n);
  vec3 sum = vec3(0.0);
  samples = max(samples, 1);
  for (int k = 0; k < samples; k++) {
    vec3 r = lobe_point(frame * uint(samples) + uint(k));
    float pdf;
    vec3 wi = mixture_sample(wo, r.x, r.yz, pdf);
    if (!(pdf > 0.0) || wi.z <= 0.0) {
      continue;
    }
    vec3 dir = wi.x * t + wi.y * b + wi.z * n;
    vec3 light = world_filtered(dir, 1.0 / (float(samples) * pdf));
    sum += analytic_value(wi, wo) * light / pdf;
  }
  sum /= float(samples);
  int sun_row = pyramid_row(int(world.w + 0.5), int(world.y + 0.5));
  int sun_count = int(texelFetch(world_pyramid, ivec2(0, sun_row), 0).a + 0.5);
  float c = cos(world.x), sn = sin(world.x);
  for (int i = 0; i < sun_count; i++) {
    vec3 m = texelFetch(world_pyramid, ivec2(2 * i, sun_row), 0).xyz;
    vec3 power = texelFetch(world_pyramid, ivec2(2 * i + 1, sun_row), 0).rgb;
    vec3 wi = to_tangent(vec3(c * m.x + sn * m.y, c * m.y - sn * m.x, m.z), t, b, n);
    if (wi.z > 0.0) {
      sum += analytic_value(wi, wo) * power;
    }
  }
  if (blender_lights > 0) {
    sum += scene_lights_sum(blender_lights, p, t, b, n, wo_world);
  }
  return sum * mblock(M_EXPOSURE);
}
