/* Colour transforms of BTFbase's MLVQ codec (reference: btf_addon/core/colour.py). */

vec3 btf_ycbcr_to_rgb(float y, float cb, float cr)
{
  vec3 rgb = vec3(1.1643828 * y + 1.5960273 * cr - 222.921,
                  1.1643828 * y - 0.39176172 * cb - 0.81296875 * cr + 135.576,
                  1.1643828 * y + 2.0172344 * cb - 276.836);
  return max(rgb, vec3(0.0));
}

float btf_srgb_encode(float c)
{
  return c > 0.0031308 ? 1.055 * pow(c, 1.0 / 2.4) - 0.055 : 12.92 * c;
}

vec3 btf_logluv_to_rgb(float l, float u, float v)
{
  float y;
  if (l < 98.381) {
    y = 0.056968 * l;
  }
  else if (l < 1204.7) {
    /* 7.3014e-30 underflows single precision in some compilers: fold it into the power. */
    y = pow((l + 884.17) * 0.0012095013, 9.9872);
  }
  else {
    y = 32.994 * exp(min(0.0047811 * l, 88.0));
  }
  float x = 0.0, z = 0.0;
  if (v > 0.0) {
    x = 9.0 / 4.0 * u / v * y;
    z = y * (3.0 * 410.0 / v - 5.0) - x / 3.0;
  }
  vec3 rgb = vec3(3.2406 * x - 1.5372 * y - 0.4986 * z,
                  -0.9689 * x + 1.8758 * y + 0.0415 * z,
                  0.0557 * x - 0.2040 * y + 1.0570 * z);
  rgb = max(rgb, vec3(0.0));
  return vec3(btf_srgb_encode(rgb.r), btf_srgb_encode(rgb.g), btf_srgb_encode(rgb.b));
}
