/* Equirectangular environment lookup oriented as Blender's Environment Texture
 * (btf_addon/core/envmap.py): s = (pi - atan2(y, x)) / 2pi, t = acos(z) / pi from the top row.
 * env_params: x = Z rotation (radians, the Mapping node's), y = strength. */

vec3 env_lookup(vec3 d)
{
  float c = cos(env_params.x), s = sin(env_params.x);
  vec3 m = normalize(vec3(c * d.x - s * d.y, s * d.x + c * d.y, d.z));
  float u = (3.14159265358979 - atan(m.y, m.x)) / 6.28318530717959;
  float v = acos(clamp(m.z, -1.0, 1.0)) / 3.14159265358979;
  ivec2 size = textureSize(environment, 0);
  ivec2 p = ivec2(int(fract(u) * float(size.x)) % size.x, min(int(v * float(size.y)), size.y - 1));
  return texelFetch(environment, p, 0).rgb * env_params.y;
}
