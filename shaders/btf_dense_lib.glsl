/* Dense (tabulated) BTFs: ring-bilinear interpolation in view and light with azimuth alignment,
 * light fade past the last ring — the same rules as btf_addon/core/grid.py and core/codecs/dense.py. */

/* The two theta rings around `theta` (clamped to the measured range) and the weight of r1: the
 * ring step of the dense and svd codecs' interpolation (core/grid.py). */
float ring_pair(int theta_off, int n_rings, float theta, out int r0, out int r1)
{
  theta = clamp(theta, ftab(theta_off), ftab(theta_off + n_rings - 1));
  r0 = 0;
  for (int r = 1; r < n_rings - 1; r++) {
    if (ftab(theta_off + r) <= theta) {
      r0 = r;
    }
  }
  r1 = r0;
  if (n_rings < 2) {
    return 0.0;
  }
  r1 = r0 + 1;
  return (theta - ftab(theta_off + r0)) / (ftab(theta_off + r1) - ftab(theta_off + r0));
}

/* Up to four (sample index, weight) pairs for a direction on a ring grid. */
void ring_weights(int theta_off, int offsets_off, int n_rings, float theta, float phi,
                  out ivec4 idx, out vec4 w)
{
  int r0, r1;
  float wt = ring_pair(theta_off, n_rings, theta, r0, r1);
  for (int k = 0; k < 2; k++) {
    int ring = (k == 0) ? r0 : r1;
    float ring_w = (k == 0) ? 1.0 - wt : wt;
    int start = itab(offsets_off + ring);
    int n = itab(offsets_off + ring + 1) - start;
    float pos = (phi - 360.0 * floor(phi / 360.0)) / (360.0 / float(n));
    int s0 = int(floor(pos)) % n;
    float wp = pos - floor(pos);
    idx[2 * k] = start + s0;
    idx[2 * k + 1] = start + (s0 + 1) % n;
    w[2 * k] = ring_w * (1.0 - wp);
    w[2 * k + 1] = ring_w * wp;
  }
}

/* Azimuth of sample i of a ring grid (its ring found by scanning the offsets). */
float ring_sample_phi(int offsets_off, int n_rings, int i)
{
  for (int r = 0; r < n_rings; r++) {
    int start = itab(offsets_off + r), end = itab(offsets_off + r + 1);
    if (i < end) {
      return float(i - start) * 360.0 / float(end - start);
    }
  }
  return 0.0;
}

vec3 dense_evaluate(vec2 uv, float theta_i, float phi_i, float theta_v, float phi_v)
{
  int width = itab(H_WIDTH), height = itab(H_HEIGHT), n_lights = itab(H_N_LIGHTS);
  int x = int(floor(fract(uv.x) * float(width))) % width;
  int y = int(floor(fract(uv.y) * float(height))) % height;
  ivec4 vi, li;
  vec4 vw, lw;
  int n_view_rings = itab(H_N_VIEW_RINGS), n_light_rings = itab(H_N_LIGHT_RINGS);
  ring_weights(itab(H_F_VIEW_THETA), itab(H_VIEW_OFFSETS), n_view_rings, theta_v, phi_v, vi, vw);
  vec3 sum = vec3(0.0);
  int data = itab(H_F_DATA);
  for (int a = 0; a < 4; a++) {
    if (vw[a] <= 0.0) {
      continue;
    }
    float view_phi = ring_sample_phi(itab(H_VIEW_OFFSETS), n_view_rings, vi[a]);
    ring_weights(itab(H_F_LIGHT_THETA), itab(H_LIGHT_OFFSETS), n_light_rings, theta_i,
                 phi_i - phi_v + view_phi, li, lw);
    for (int b = 0; b < 4; b++) {
      int base = data + (((vi[a] * n_lights + li[b]) * height + y) * width + x) * 3;
      sum += vw[a] * lw[b] * vec3(ftab(base), ftab(base + 1), ftab(base + 2));
    }
  }
  float last = ftab(itab(H_F_LIGHT_THETA) + n_light_rings - 1);
  if (theta_i > last) {
    sum *= cos(radians(theta_i)) / cos(radians(last));
  }
  return sum;
}
