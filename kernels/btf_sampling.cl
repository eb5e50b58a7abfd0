/* The BTF's direction sampling (include/btf_sampling.h) on its own, for tests and benchmarks:
 * draws from bsdf_sample and evaluates bsdf_pdf for one material (its two packed streams) and
 * one view direction wo (tangent frame), exactly as render_env_mis calls them. */

#include "btf_packed.h"
#include "btf_sampling.h"

/* n directions (wi: 3n floats) and their pdf from the points u (2n floats) and lobe choices:
 * the pdf bsdf_sample states (pdf) and bsdf_pdf's of the same direction (pdf_again). */
__kernel void sample_directions(const int n, __global const float *I, __global const float *F,
                                const float4 wo, __global const float *u,
                                __global const float *choice, __global float *wi,
                                __global float *pdf, __global float *pdf_again)
{
  int i = get_global_id(0);
  if (i >= n) {
    return;
  }
  float p;
  float3 d = bsdf_sample(I, F, wo.xyz, choice[i], vload2(i, u), &p);
  vstore3(d, i, wi);
  pdf[i] = p;
  pdf_again[i] = bsdf_pdf(I, F, d, wo.xyz);
}

/* bsdf_pdf of n given directions wi (3n floats). */
__kernel void direction_pdf(const int n, __global const float *I, __global const float *F,
                            const float4 wo, __global const float *wi, __global float *pdf)
{
  int i = get_global_id(0);
  if (i >= n) {
    return;
  }
  pdf[i] = bsdf_pdf(I, F, vload3(i, wi), wo.xyz);
}
