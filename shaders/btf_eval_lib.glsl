/* One entry point for every codec: value (the project's convention) for a valid query. */

float ggx_lambda(float alpha2, float c)
{
  float c2 = max(c, 1e-6);
  c2 *= c2;
  return 0.5 * (-1.0 + sqrt(1.0 + alpha2 * max(1.0 / c2 - 1.0, 0.0)));
}

vec3 btf_direction(float theta_deg, float phi_deg)
{
  float t = radians(theta_deg), p = radians(phi_deg);
  return vec3(sin(t) * cos(p), sin(t) * sin(p), cos(t));
}

/* A direction in the tangent frame (t, b, n), and as (θ, φ) degrees with φ in [0, 360): what
 * btf_evaluate takes (as btf_theta_phi_deg in kernels/include/btf_packed.h). */
vec3 to_tangent(vec3 d, vec3 t, vec3 b, vec3 n)
{
  return vec3(dot(d, t), dot(d, b), dot(d, n));
}

vec2 theta_phi_deg(vec3 d)
{
  float phi = degrees(atan(d.y, d.x));
  return vec2(degrees(acos(clamp(d.z, -1.0, 1.0))), phi < 0.0 ? phi + 360.0 : phi);
}

/* An analytic codec's value for unit tangent-frame directions wi (light) and wo (view): the
 * same in any frame about the normal (the codecs are isotropic), so a caller with vectors
 * (shaders/lobe_lib.glsl) needs no angles and no mapping. */
vec3 analytic_value(vec3 wi, vec3 wo)
{
  int codec = itab(H_CODEC);
  vec3 albedo = vec3(ftab(F_ALBEDO), ftab(F_ALBEDO + 1), ftab(F_ALBEDO + 2));
  if (codec == CODEC_LAMBERTIAN) {
    return albedo * (max(wi.z, 0.0) / 3.14159265358979);
  }
  /* CODEC_GGX: D·G/(4 cos θo), as btf_addon/core/codecs/analytic.py */
  float alpha2 = ftab(F_ALPHA2);
  vec3 h = wi + wo;
  float h_len = length(h);
  float cos_h = h_len > 1e-12 ? h.z / h_len : 0.0;
  float denom = 1.0 + (alpha2 - 1.0) * cos_h * cos_h;
  float d = alpha2 / (3.14159265358979 * denom * denom);
  float g = 1.0 / (1.0 + ggx_lambda(alpha2, wi.z) + ggx_lambda(alpha2, wo.z));
  float ggx = d * g / (4.0 * max(wo.z, 1e-6));
  if (codec == CODEC_GGX) {
    return albedo * ggx;
  }
  /* CODEC_PRINCIPLED, as PrincipledBTF in btf_addon/core/codecs/analytic.py */
  float metallic = ftab(F_METALLIC), sigma = ftab(F_DIFFUSE_ROUGHNESS);
  float f0d = ftab(F_SPECULAR_F0);
  vec3 f0 = f0d + (albedo - f0d) * metallic;
  float cos_d = h_len > 1e-12 ? clamp(dot(h, wo) / h_len, 0.0, 1.0) : 0.0;
  vec3 fresnel = f0 + (1.0 - f0) * pow(1.0 - cos_d, 5.0);
  float s = dot(wi, wo) - wi.z * wo.z;
  float a = 1.0 / (3.14159265358979 + (3.14159265358979 / 2.0 - 2.0 / 3.0) * sigma);
  float ci_over_t = s > 0.0 ? wi.z / max(max(wi.z, wo.z), 1e-6) : wi.z;
  float on = a * wi.z + sigma * a * s * ci_over_t;
  float fresnel_view = f0d + (1.0 - f0d) * pow(1.0 - clamp(wo.z, 0.0, 1.0), 5.0);
  float weight = (1.0 - metallic) * (1.0 - fresnel_view);
  return weight * albedo * on + fresnel * ggx;
}

/* uv: texture coordinates; angles in degrees with theta in [0, 90]. */
vec3 btf_evaluate(vec2 uv, float theta_i, float phi_i, float theta_v, float phi_v)
{
  int codec = itab(H_CODEC);
  if (codec == CODEC_MLVQ) {
    return mlvq_decode(uv, theta_i, phi_i, theta_v, phi_v) * ftab(F_VALUE_SCALE);
  }
  if (codec == CODEC_DENSE) {
    return dense_evaluate(uv, theta_i, phi_i, theta_v, phi_v);
  }
  if (codec == CODEC_SVD) {
    return svd_evaluate(uv, theta_i, phi_i, theta_v, phi_v) * ftab(F_VALUE_SCALE);
  }
  return analytic_value(btf_direction(theta_i, phi_i), btf_direction(theta_v, phi_v));
}

/* btf_evaluate with spatial filtering (btf_addon/core/mapping.py filtered_evaluate, as
 * btf_filtered in kernels/include/btf_packed.h): FILTER_LINEAR decodes the 4 texels around uv
 * at their centres and blends them bilinearly, wrapping around the tile; FILTER_NEAREST (and
 * one-texel BTFs) decode once at uv. light, view: (theta, phi) degrees. */
vec3 btf_filtered(int texel_filter, vec2 uv, vec2 light, vec2 view)
{
  int width = itab(H_WIDTH), height = itab(H_HEIGHT);
  if (texel_filter != FILTER_LINEAR || width * height <= 1) {
    return btf_evaluate(uv, light.x, light.y, view.x, view.y);
  }
  vec2 size = vec2(float(width), float(height));
  vec2 s = (uv - floor(uv)) * size - 0.5; /* mod first: large uv keep their fraction */
  vec2 i0 = floor(s);
  vec2 f = s - i0;
  float x0 = mod(i0.x, size.x), y0 = mod(i0.y, size.y);
  float x1 = mod(x0 + 1.0, size.x), y1 = mod(y0 + 1.0, size.y);
  vec3 sum = vec3(0.0);
  for (int k = 0; k < 4; k++) {
    float x = (k % 2 == 1) ? x1 : x0, y = (k >= 2) ? y1 : y0;
    float w = ((k % 2 == 1) ? f.x : 1.0 - f.x) * ((k >= 2) ? f.y : 1.0 - f.y);
    vec2 centre = vec2((x + 0.5) / size.x, (y + 0.5) / size.y);
    sum += w * btf_evaluate(centre, light.x, light.y, view.x, view.y);
  }
  return sum;
}
