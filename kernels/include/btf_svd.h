/* The svd codec (UBO2014 DFMF) from the packed layout: btf_addon/core/codecs/svd.py is the reference.
 * Per channel c: value y_c = sum_k U_c[pair, k] * SV_c[texel, k]; the colour transform turns
 * y into RGB per measured direction pair; pairs are blended ring-bilinearly (view, then light
 * at the same azimuth relative to the view), as the dense codec but with each sample's own
 * azimuth from a table. Included by btf_packed.h (needs btf_mod, ITAB, FTAB). */
#ifndef BTF_SVD_H
#define BTF_SVD_H

/* Colour table: pre, eps, cosine_in_data, matrix (row-major 3x3), offset (3). */
inline float3 svd_colour(Stream F, int colour, float3 y)
{
  int pre = (int)FTAB(colour);
  float eps = FTAB(colour + 1);
  if (pre == 1) {
    y.x = exp(y.x) - eps;
  }
  else if (pre == 2) {
    y = exp(y) - eps;
  }
  int m = colour + 3;
  return (float3)(FTAB(m) * y.x + FTAB(m + 1) * y.y + FTAB(m + 2) * y.z + FTAB(colour + 12),
                  FTAB(m + 3) * y.x + FTAB(m + 4) * y.y + FTAB(m + 5) * y.z + FTAB(colour + 13),
                  FTAB(m + 6) * y.x + FTAB(m + 7) * y.y + FTAB(m + 8) * y.z + FTAB(colour + 14));
}

/* One channel: dot of U row `pair` and SV row `texel` (rank from the channel table). */
inline float svd_channel(Stream I, Stream F, int channels, int c, int pair, int texel)
{
  int rank = ITAB(channels + 3 * c);
  int u = ITAB(channels + 3 * c + 1) + pair * rank;
  int sv = ITAB(channels + 3 * c + 2) + texel * rank;
  float sum = 0.0f;
  for (int k = 0; k < rank; k++) {
    sum += FTAB(u + k) * FTAB(sv + k);
  }
  return sum;
}

/* ring_weights (btf_packed.h) with every sample's own azimuth (table phi_off, ring order,
 * increasing within a ring): as svd.ring_weights in btf_addon/core/codecs/svd.py. */
inline void svd_ring_weights(Stream I, Stream F, int theta_off, int offsets_off, int phi_off,
                             int n_rings, float theta, float phi, int idx[4], float w[4])
{
  int r0, r1;
  float wt = ring_pair(F, theta_off, n_rings, theta, &r0, &r1);
  float pos = btf_mod(phi, 360.0f);
  for (int k = 0; k < 2; k++) {
    int ring = k ? r1 : r0;
    float ring_w = k ? wt : 1.0f - wt;
    int start = ITAB(offsets_off + ring);
    int n = ITAB(offsets_off + ring + 1) - start;
    int j = n - 1;
    for (int s = 0; s < n; s++) {
      if (FTAB(phi_off + start + s) <= pos) {
        j = s;
      }
    }
    int next = (j + 1) % n;
    float ph = FTAB(phi_off + start + j);
    float span = btf_mod(FTAB(phi_off + start + next) - ph, 360.0f);
    span = span <= 0.0f ? 360.0f : span;
    float wp = btf_mod(pos - ph, 360.0f) / span;
    idx[2 * k] = start + j;
    idx[2 * k + 1] = start + next;
    w[2 * k] = ring_w * (1.0f - wp);
    w[2 * k + 1] = ring_w * wp;
  }
}

/* Angles in degrees, theta <= 90: RGB before value_scale (the dispatch multiplies by it). */
inline float3 svd_evaluate(Stream I, Stream F, float2 uv, float theta_i, float phi_i,
                           float theta_v, float phi_v)
{
  int width = ITAB(H_WIDTH), height = ITAB(H_HEIGHT), n_lights = ITAB(H_N_LIGHTS);
  int x = ((int)floor(btf_mod(uv.x, 1.0f) * width)) % width;
  int y = ((int)floor(btf_mod(uv.y, 1.0f) * height)) % height;
  int texel = y * width + x;
  int channels = ITAB(H_SVD_CHANNELS), colour = ITAB(H_F_SVD_COLOUR);
  int vi[4], li[4];
  float vw[4], lw[4];
  int n_view_rings = ITAB(H_N_VIEW_RINGS), n_light_rings = ITAB(H_N_LIGHT_RINGS);
  int view_phi_off = ITAB(channels + 9), light_phi_off = ITAB(channels + 10);
  svd_ring_weights(I, F, ITAB(H_F_VIEW_THETA), ITAB(H_VIEW_OFFSETS), view_phi_off, n_view_rings,
                   theta_v, phi_v, vi, vw);
  float3 sum = (float3)(0.0f);
  for (int a = 0; a < 4; a++) {
    if (vw[a] <= 0.0f) {
      continue;
    }
    float view_phi = FTAB(view_phi_off + vi[a]);
    svd_ring_weights(I, F, ITAB(H_F_LIGHT_THETA), ITAB(H_LIGHT_OFFSETS), light_phi_off,
                     n_light_rings, theta_i, phi_i - phi_v + view_phi, li, lw);
    for (int b = 0; b < 4; b++) {
      float w = vw[a] * lw[b];
      if (w <= 0.0f) {
        continue;
      }
      int pair = vi[a] * n_lights + li[b];
      float3 yc = (float3)(svd_channel(I, F, channels, 0, pair, texel),
                           svd_channel(I, F, channels, 1, pair, texel),
                           svd_channel(I, F, channels, 2, pair, texel));
      sum += w * svd_colour(F, colour, yc);
    }
  }
  float cos_i = cos(radians(theta_i));
  if (FTAB(colour + 2) == 0.0f) {
    return sum * cos_i; /* the data lacks the cosine of incidence */
  }
  float last = FTAB(ITAB(H_F_LIGHT_THETA) + n_light_rings - 1);
  if (theta_i > last) {
    sum *= cos_i / cos(radians(last));
  }
  return sum;
}

#endif
