/* Equirectangular environment lookup oriented as Blender's Environment Texture
 * (btf_addon/core/sampling/envmap.py): s = (pi - atan2(y, x)) / 2pi, t = acos(z) / pi from the top row.
 * env_params: x = Z rotation (radians, the Mapping node's), y = strength. */

vec3 env_lookup(vec3 d)
{
  float c = cos(env_params.x), s = sin(env_params.x);
  vec3 m = normalize(vec3(c * d.x - s * d.y, s * d.x + c * d.y, d.z));
  float u = (3.14159265358979 - atan(m.y, m.x)) / 6.28318530717959;
  float v = acos(clamp(m.z, -1.0, 1.0)) / 3.14159265358979;
  /* Bilinear, wrapping across the seam, as the Environment Texture's default (Linear). Rows
   * were uploaded top first, so texture t = 0 is the zenith. */
  return texture(environment, vec2(u, v)).rgb * env_params.y;
}
