/* Blender's lights in the viewport, as the final render's deterministic mode lights them
 * (kernels/include/btf_lights.h: a point light's centre, an area light's 4 × 4 cell centres;
 * units and layout: btf_addon/scene/lights.py, 5 RGBA texels per light) but without shadows:
 * the viewport has none. */

#define LIGHT_SUN 0
#define LIGHT_AREA 2
#define AREA_GRID 4

vec4 light_texel(int light, int row)
{
  return texelFetch(scene_lights, ivec2(5 * light + row, 0), 0);
}

/* E for the light's point u ∈ [0, 1)², with the direction towards it. */
vec3 scene_light_sample(int light, vec3 p, vec2 u, out vec3 dir)
{
  vec4 r0 = light_texel(light, 0), r1 = light_texel(light, 1), r2 = light_texel(light, 2);
  int type = int(r0.w + 0.5);
  if (type == LIGHT_SUN) {
    dir = r0.xyz;
    return r1.rgb;
  }
  if (type == LIGHT_AREA) {
    vec4 r3 = light_texel(light, 3), r4 = light_texel(light, 4);
    float a = 2.0 * u.x - 1.0, b = 2.0 * u.y - 1.0;
    float area = 4.0 * length(cross(r3.xyz, r4.xyz));
    if (r4.w > 0.5) {
      float r = sqrt(u.x), phi = 6.28318530717959 * u.y;
      a = r * cos(phi);
      b = r * sin(phi);
      area *= 0.785398163397448;
    }
    vec3 d = r0.xyz + a * r3.xyz + b * r4.xyz - p;
    float len = length(d);
    dir = d / max(len, 1e-30);
    float cos_light = -dot(dir, r2.xyz);
    return cos_light > 0.0 ? r1.rgb * (cos_light * area / max(len * len, 1e-12)) : vec3(0.0);
  }
  vec3 d = r0.xyz - p;
  float len = length(d);
  dir = d / max(len, 1e-30);
  float mask = 1.0;
  if (r2.w > -1.0) { /* a spot */
    float cos_gamma = -dot(dir, r2.xyz);
    float smooth_factor = light_texel(light, 3).w;
    if (smooth_factor <= 0.0) {
      mask = cos_gamma > r2.w ? 1.0 : 0.0;
    }
    else {
      float x = clamp((cos_gamma - r2.w) * smooth_factor, 0.0, 1.0);
      mask = x * x * (3.0 - 2.0 * x);
    }
  }
  return r1.rgb * (mask / max(len * len, 1e-12));
}

/* Sum over the lights at p with the shading frame (t, b, n), seen from wo_world; the BTF
 * through the fragment's mapping (btf_mapping_lib.glsl map_point ran first). */
vec3 scene_lights_sum(int count, vec3 p, vec3 t, vec3 b, vec3 n, vec3 wo_world)
{
  vec3 sum = vec3(0.0);
  for (int i = 0; i < count; i++) {
    int samples = int(light_texel(i, 0).w + 0.5) == LIGHT_AREA ? AREA_GRID * AREA_GRID : 1;
    for (int k = 0; k < samples; k++) {
      vec2 u = vec2((float(k % AREA_GRID) + 0.5) / float(AREA_GRID),
                    (float(k / AREA_GRID) + 0.5) / float(AREA_GRID));
      vec3 dir;
      vec3 e = scene_light_sample(i, p, u, dir);
      vec3 wi = to_tangent(dir, t, b, n);
      if (wi.z <= 0.0 || !(e.r + e.g + e.b > 0.0)) {
        continue;
      }
      sum += btf_mapped(n, dir, wo_world) * e / float(samples);
    }
  }
  return sum;
}
