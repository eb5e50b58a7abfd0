/* The film's pixel filter, importance-sampled: a sample's offset from the pixel centre is drawn
 * with the filter's own distribution, so every sample weighs the same and the pixel's mean
 * converges to the filtered image. Separable: x and y each from the 1D profile. As Cycles
 * (scene/film.cpp) the distribution comes as an inverse-CDF table, built on the host from the
 * closed-form CDFs (btf_addon/render/pixel_filter.py ``PixelFilter.table``): entry i is the
 * offset (pixels, ≥ 0) below which the fraction i / (FILTER_TABLE_SIZE − 1) of the half
 * profile's mass lies. A lookup is one interpolation, where inverting the CDF here took 48
 * evaluations of it per sample — more than the rest of a Virtual Lights subpixel. */
#ifndef BTF_FILTER_H
#define BTF_FILTER_H

/* FILTER_TABLE_SIZE arrives as a build define (btf_addon/cl/renderer.py program_defines, from
 * render/pixel_filter.py): the table's size has one definition. */
#ifndef FILTER_TABLE_SIZE
#error "FILTER_TABLE_SIZE must be defined by the build (cl/renderer.py program_defines)"
#endif

/* u in [0, 1) → offset in pixels; monotone (u = ½ → 0), so stratified u stay stratified. */
inline float filter_sample_1d(__global const float *table, float u)
{
  float t = fmin(fabs(2.0f * u - 1.0f), 1.0f) * (FILTER_TABLE_SIZE - 1);
  int i = min((int)t, FILTER_TABLE_SIZE - 2);
  float x = mix(table[i], table[i + 1], t - (float)i);
  return u < 0.5f ? -x : x;
}

/* A 2D offset from the pixel centre (x right, y down, pixels) for uniform u. */
inline float2 filter_sample(__global const float *table, float2 u)
{
  return (float2)(filter_sample_1d(table, u.x), filter_sample_1d(table, u.y));
}

#endif
