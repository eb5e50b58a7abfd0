/* The svd codec (UBO2014 DFMF), as kernels/include/btf_svd.h and btf_addon/core/codecs/svd.py: per
 * measured direction pair y_c = sum_k U_c[pair, k] * SV_c[texel, k], the colour transform to
 * RGB, then the dense codec's ring-bilinear blend with each sample's own azimuth. */

/* Colour table: pre, eps, cosine_in_data, matrix (row-major 3x3), offset (3). */
vec3 svd_colour(int colour, vec3 y)
{
  int pre = int(ftab(colour));
  float eps = ftab(colour + 1);
  if (pre == 1) {
    y.x = exp(y.x) - eps;
  }
  else if (pre == 2) {
    y = exp(y) - eps;
  }
  int m = colour + 3;
  return vec3(ftab(m) * y.x + ftab(m + 1) * y.y + ftab(m + 2) * y.z + ftab(colour + 12),
              ftab(m + 3) * y.x + ftab(m + 4) * y.y + ftab(m + 5) * y.z + ftab(colour + 13),
              ftab(m + 6) * y.x + ftab(m + 7) * y.y + ftab(m + 8) * y.z + ftab(colour + 14));
}

float svd_channel(int channels, int c, int pair, int texel)
{
  int rank = itab(channels + 3 * c);
  int u = itab(channels + 3 * c + 1) + pair * rank;
  int sv = itab(channels + 3 * c + 2) + texel * rank;
  float sum = 0.0;
  for (int k = 0; k < rank; k++) {
    sum += ftab(u + k) * ftab(sv + k);
  }
  return sum;
}

/* ring_weights (btf_dense_lib.glsl) with every sample's own azimuth (table phi_off, ring
 * order, increasing within a ring): as svd.ring_weights in btf_addon/core/codecs/svd.py. */
void svd_ring_weights(int theta_off, int offsets_off, int phi_off, int n_rings, float theta,
                      float phi, out ivec4 idx, out vec4 w)
{
  int r0, r1;
  float wt = ring_pair(theta_off, n_rings, theta, r0, r1);
  float pos = phi - 360.0 * floor(phi / 360.0);
  for (int k = 0; k < 2; k++) {
    int ring = (k == 0) ? r0 : r1;
    float ring_w = (k == 0) ? 1.0 - wt : wt;
    int start = itab(offsets_off + ring);
    int n = itab(offsets_off + ring + 1) - start;
    int j = n - 1;
    for (int s = 0; s < n; s++) {
      if (ftab(phi_off + start + s) <= pos) {
        j = s;
      }
    }
    int next = (j + 1) % n;
    float ph = ftab(phi_off + start + j);
    float span = ftab(phi_off + start + next) - ph;
    span -= 360.0 * floor(span / 360.0);
    span = span <= 0.0 ? 360.0 : span;
    float d = pos - ph;
    d -= 360.0 * floor(d / 360.0);
    float wp = d / span;
    idx[2 * k] = start + j;
    idx[2 * k + 1] = start + next;
    w[2 * k] = ring_w * (1.0 - wp);
    w[2 * k + 1] = ring_w * wp;
  }
}

/* Angles in degrees, theta <= 90: RGB before value_scale (the dispatch multiplies by it). */
vec3 svd_evaluate(vec2 uv, float theta_i, float phi_i, float theta_v, float phi_v)
{
  int width = itab(H_WIDTH), height = itab(H_HEIGHT), n_lights = itab(H_N_LIGHTS);
  int x = int(floor(fract(uv.x) * float(width))) % width;
  int y = int(floor(fract(uv.y) * float(height))) % height;
  int texel = y * width + x;
  int channels = itab(H_SVD_CHANNELS), colour = itab(H_F_SVD_COLOUR);
  ivec4 vi, li;
  vec4 vw, lw;
  int n_view_rings = itab(H_N_VIEW_RINGS), n_light_rings = itab(H_N_LIGHT_RINGS);
  int view_phi_off = itab(channels + 9), light_phi_off = itab(channels + 10);
  svd_ring_weights(itab(H_F_VIEW_THETA), itab(H_VIEW_OFFSETS), view_phi_off, n_view_rings, theta_v,
                   phi_v, vi, vw);
  vec3 sum = vec3(0.0);
  for (int a = 0; a < 4; a++) {
    if (vw[a] <= 0.0) {
      continue;
    }
    float view_phi = ftab(view_phi_off + vi[a]);
    svd_ring_weights(itab(H_F_LIGHT_THETA), itab(H_LIGHT_OFFSETS), light_phi_off, n_light_rings,
                     theta_i, phi_i - phi_v + view_phi, li, lw);
    for (int b = 0; b < 4; b++) {
      float w = vw[a] * lw[b];
      if (w <= 0.0) {
        continue;
      }
      int pair = vi[a] * n_lights + li[b];
      vec3 yc = vec3(svd_channel(channels, 0, pair, texel), svd_channel(channels, 1, pair, texel),
                     svd_channel(channels, 2, pair, texel));
      sum += w * svd_colour(colour, yc);
    }
  }
  float cos_i = cos(radians(theta_i));
  if (ftab(colour + 2) == 0.0) {
    return sum * cos_i; /* the data lacks the cosine of incidence */
  }
  float last = ftab(itab(H_F_LIGHT_THETA) + n_light_rings - 1);
  if (theta_i > last) {
    sum *= cos_i / cos(radians(last));
  }
  return sum;
}
