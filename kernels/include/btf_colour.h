/* Colour transforms of BTFbase's MLVQ codec (see btf_addon/core/colour.py, the reference). */
#ifndef BTF_COLOUR_H
#define BTF_COLOUR_H

#include "btf_builtins.h"

/* Studio-swing BT.601 YCbCr (8-bit scale) -> RGB (8-bit scale) before the clamp of negatives,
 * for floats or vectors of them alike (mlvq_walk_rgb converts four 2D functions at once and
 * clamps with BTF_VMAX). */
#define BTF_YCBCR_R(y, cb, cr) (1.1643828f * (y) + 1.5960273f * (cr) - 222.921f)
#define BTF_YCBCR_G(y, cb, cr) \
  (1.1643828f * (y) - 0.39176172f * (cb) - 0.81296875f * (cr) + 135.576f)
#define BTF_YCBCR_B(y, cb, cr) (1.1643828f * (y) + 2.0172344f * (cb) - 276.836f)

inline float btf_srgb_encode(float c)
{
  return c > 0.0031308f ? 1.055f * pow(c, 1.0f / 2.4f) - 0.055f : 12.92f * c;
}

/* Mantiuk 2006 LogLuv (luma code, u, v) -> RGB, sRGB-encoded as the original HDR decoder. */
inline float3 btf_logluv_to_rgb(float l, float u, float v)
{
  float y;
  if (l < 98.381f) {
    y = 0.056968f * l;
  }
  else if (l < 1204.7f) {
    y = 7.3014e-30f * pow(l + 884.17f, 9.9872f);
  }
  else {
    y = 32.994f * exp(fmin(0.0047811f * l, 88.0f));
  }
  float x = 0.0f, z = 0.0f;
  if (v > 0.0f) {
    x = 9.0f / 4.0f * u / v * y;
    z = y * (3.0f * 410.0f / v - 5.0f) - x / 3.0f;
  }
  float3 rgb = (float3)(3.2406f * x - 1.5372f * y - 0.4986f * z,
                        -0.9689f * x + 1.8758f * y + 0.0415f * z,
                        0.0557f * x - 0.2040f * y + 1.0570f * z);
  rgb = fmax(rgb, (float3)(0.0f));
  return (float3)(btf_srgb_encode(rgb.x), btf_srgb_encode(rgb.y), btf_srgb_encode(rgb.z));
}

#endif
