/* Directions for a path to continue in: the BTF's own importance sampling where its lobe is
 * known. Analytic GGX lobes (codecs ggx and principled) are sampled by their distribution of
 * visible normals (Heitz 2018, "Sampling the GGX Distribution of Visible Normals") mixed with
 * cosine sampling; measured and tabulated BTFs have no closed-form lobe and use cosine sampling
 * alone. The pdf of the mixture is what MIS weighs the environment's samples against. */
#ifndef BTF_SAMPLING_H
#define BTF_SAMPLING_H

#include "btf_packed.h"

/* Probability of drawing from the GGX lobe: 0 where the codec has none. A principled material
 * is a specular layer over a diffuse base: half its samples each, more as it gets metallic. */
inline float ggx_lobe_probability(Stream I, Stream F)
{
  int codec = ITAB(H_CODEC);
  if (codec == CODEC_GGX) {
    return 0.9f;
  }
  if (codec == CODEC_PRINCIPLED) {
    return 0.5f + 0.4f * FTAB(F_METALLIC);
  }
  return 0.0f;
}

/* pdf (solid angle) of reflecting wo into wi through a visible normal. */
inline float ggx_vndf_pdf(float alpha2, float3 wi, float3 wo)
{
  if (wi.z <= 0.0f || wo.z <= 0.0f) {
    return 0.0f;
  }
  float3 m = normalize(wi + wo);
  float g1 = 1.0f / (1.0f + ggx_lambda(alpha2, wo.z));
  return g1 * ggx_d(alpha2, m.z) / (4.0f * wo.z);
}

inline float3 ggx_vndf_sample(float alpha2, float3 wo, float2 u)
{
  float alpha = sqrt(alpha2);
  float3 vh = normalize((float3)(alpha * wo.x, alpha * wo.y, wo.z));
  float len2 = vh.x * vh.x + vh.y * vh.y;
  float3 t1 = len2 > 0.0f ? (float3)(-vh.y, vh.x, 0.0f) * rsqrt(len2) : (float3)(1.0f, 0.0f, 0.0f);
  float3 t2 = cross(vh, t1);
  float r = sqrt(u.x), phi = 2.0f * M_PI_F * u.y;
  float p1 = r * cos(phi), p2 = r * sin(phi);
  float s = 0.5f * (1.0f + vh.z);
  p2 = (1.0f - s) * sqrt(fmax(1.0f - p1 * p1, 0.0f)) + s * p2;
  float3 nh = p1 * t1 + p2 * t2 + sqrt(fmax(1.0f - p1 * p1 - p2 * p2, 0.0f)) * vh;
  float3 m = normalize((float3)(alpha * nh.x, alpha * nh.y, fmax(nh.z, 1e-6f)));
  return 2.0f * dot(wo, m) * m - wo;
}

/* The mixture's pdf of wi (tangent frame). */
inline float bsdf_pdf(Stream I, Stream F, float3 wi, float3 wo)
{
  float cosine = fmax(wi.z, 0.0f) / M_PI_F;
  float p = ggx_lobe_probability(I, F);
  return p > 0.0f ? p * ggx_vndf_pdf(FTAB(F_ALPHA2), wi, wo) + (1.0f - p) * cosine : cosine;
}

/* A direction from the mixture: `choice` in [0, 1) picks the lobe, `u` places the sample. */
inline float3 bsdf_sample(Stream I, Stream F, float3 wo, float choice, float2 u)
{
  float p = ggx_lobe_probability(I, F);
  if (choice < p) {
    return ggx_vndf_sample(FTAB(F_ALPHA2), wo, u);
  }
  float r = sqrt(u.x), phi = 2.0f * M_PI_F * u.y;
  return (float3)(r * cos(phi), r * sin(phi), sqrt(fmax(1.0f - u.x, 0.0f)));
}

#endif
