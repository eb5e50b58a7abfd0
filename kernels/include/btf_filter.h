/* The film's pixel filter, importance-sampled: a sample's offset from the pixel centre is drawn
 * with the filter's own distribution, so every sample weighs the same and the pixel's mean
 * converges to the filtered image (Cycles: scene/film.cpp builds the same distribution as an
 * inverse-CDF table). Separable: x and y each from the 1D profile. Reference and the profiles'
 * formulas: btf_addon/render/pixel_filter.py (this file inverts the same closed-form CDFs by
 * bisection; a handful of sines per sample next to a path's BTF lookups).
 *
 * filter_type: FILTER_BOX | FILTER_GAUSSIAN | FILTER_BLACKMAN_HARRIS (FilterType's values);
 * filter_width in pixels; a width ≤ 0 gives the pixel centre. */
#ifndef BTF_FILTER_H
#define BTF_FILTER_H

#define FILTER_BOX 0
#define FILTER_GAUSSIAN 1
#define FILTER_BLACKMAN_HARRIS 2
#define FILTER_BISECTION_STEPS 24

/* Half the support in pixels. */
inline float filter_radius(int type, float width)
{
  return (type == FILTER_BOX ? 0.5f : (type == FILTER_GAUSSIAN ? 1.5f : 1.0f)) * width;
}

/* ∫₀ˣ of the 1D profile (peak 1 at the centre), 0 ≤ x ≤ radius. */
inline float filter_cdf(int type, float width, float x)
{
  if (type == FILTER_BOX) {
    return x;
  }
  if (type == FILTER_GAUSSIAN) { /* exp(−8 v²/w²) */
    float k = sqrt(8.0f) / width;
    return sqrt(M_PI_F) / (2.0f * k) * erf(k * x);
  }
  /* Blackman-Harris over |v| ≤ w: θ = 2π(v/2w + ½) */
  float t = 2.0f * M_PI_F * (x / (2.0f * width) + 0.5f);
  return 0.35875f * x - (width / M_PI_F) * (0.48829f * sin(t) - 0.07064f * sin(2.0f * t) +
                                            0.0038933333f * sin(3.0f * t));
}

/* u in [0, 1) → offset in pixels; monotone (u = ½ → 0), so stratified u stay stratified. */
inline float filter_sample_1d(int type, float width, float u)
{
  float r = filter_radius(type, width);
  if (!(r > 0.0f)) {
    return 0.0f;
  }
  float target = fabs(2.0f * u - 1.0f) * filter_cdf(type, width, r);
  float lo = 0.0f, hi = r;
  for (int i = 0; i < FILTER_BISECTION_STEPS; i++) {
    float mid = 0.5f * (lo + hi);
    if (filter_cdf(type, width, mid) < target) {
      lo = mid;
    }
    else {
      hi = mid;
    }
  }
  return (u < 0.5f ? -0.5f : 0.5f) * (lo + hi);
}

/* A 2D offset from the pixel centre (x right, y down, pixels) for uniform u. */
inline float2 filter_sample(int type, float width, float2 u)
{
  return (float2)(filter_sample_1d(type, width, u.x), filter_sample_1d(type, width, u.y));
}

#endif
