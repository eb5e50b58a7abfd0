/* BTFbase MLVQ decoding in GLSL: the same steps as btf_addon/core/mlvq.py (the reference, which
 * documents each level) and kernels/include/btf_mlvq.h. Needs btf_tables_lib, btf_colour_lib. */

float mlvq_pdf1(int s, int i, float w, int n_beta)
{
  int row = itab(H_F_PDF1) + s * n_beta;
  float p0 = ftab(row + i), p1 = ftab(row + i + 1);
  float m0 = (i == 0) ? p1 - p0 : 0.5 * (p1 - ftab(row + i - 1));
  float m1 = (i == n_beta - 2) ? p1 - p0 : 0.5 * (p1 - p0);
  float t2 = w * w, t3 = t2 * w;
  float h01 = -2.0 * t3 + 3.0 * t2;
  float h00 = 1.0 - h01;
  float h11 = t3 - t2;
  float h10 = h11 - t2 + w;
  return h00 * p0 + h10 * m0 + h01 * p1 + h11 * m1;
}

vec2 mlvq_ab(int c, int i, float w, int n_beta)
{
  int row = itab(H_INDEX_AB) + c * n_beta;
  int ab = itab(H_F_AB_COLORS);
  int a = itab(row + i), b = itab(row + i + 1);
  vec2 ca = vec2(ftab(ab + 2 * a), ftab(ab + 2 * a + 1));
  vec2 cb = vec2(ftab(ab + 2 * b), ftab(ab + 2 * b + 1));
  return ca * (1.0 - w) + cb * w;
}

vec3 mlvq_pdf2(int idx2, int ia, float wa, int ib, float wb, int n_beta, int n_alpha)
{
  int lum_fn = itab(itab(H_PDF2_INDICES) + 2 * idx2);
  int col_fn = itab(itab(H_PDF2_INDICES) + 2 * idx2 + 1);
  float lum = 0.0;
  vec2 cbcr = vec2(0.0);
  for (int k = 0; k < 2; k++) {
    int a = ia + k;
    float w = (k == 1) ? wa : 1.0 - wa;
    int li = lum_fn * n_alpha + a;
    lum += w * ftab(itab(H_F_PDF2_SCALE) + li) *
           mlvq_pdf1(itab(itab(H_PDF2_SLICES) + li), ib, wb, n_beta);
    cbcr += w * mlvq_ab(itab(itab(H_PDF2_COLOURS) + col_fn * n_alpha + a), ib, wb, n_beta);
  }
  if (itab(H_HDR) != 0) {
    return btf_logluv_to_rgb(lum, cbcr.x, cbcr.y);
  }
  return btf_ycbcr_to_rgb(lum, cbcr.x, cbcr.y);
}

void mlvq_uniform_index(float x, float step, int max_index, out int i, out float w)
{
  i = clamp(int(x / step), 0, max_index);
  w = (x - float(i) * step) / step;
}

float mlvq_mod(float x, float m)
{
  return x - m * floor(x / m);
}

/* Angles in degrees, theta in [0, 90]: the decoder's raw RGB. */
vec3 mlvq_decode(vec2 uv, float theta_i, float phi_i, float theta_v, float phi_v)
{
  int n_beta = itab(H_N_BETA), n_alpha = itab(H_N_ALPHA);
  int n_theta = itab(H_N_THETA), n_phi = itab(H_N_PHI);
  int width = itab(H_WIDTH), height = itab(H_HEIGHT);
  int x = (int(floor(mlvq_mod(uv.x, 1.0) * float(width))) - itab(H_COLS_OFFSET)) % width;
  int y = (int(floor(mlvq_mod(uv.y, 1.0) * float(height))) - itab(H_ROWS_OFFSET)) % height;
  x = (x + width) % width;
  y = (y + height) % height;

  float view_phi = mlvq_mod(360.0 - phi_v, 360.0);
  float light_phi = mlvq_mod((360.0 - phi_i) - (90.0 + view_phi), 360.0);
  float th = radians(theta_i), ph = radians(light_phi);
  float bx = cos(ph) * sin(th), by = sin(ph) * sin(th);
  float beta = asin(clamp(bx, -1.0, 1.0));
  float cos_beta = cos(beta);
  float alpha = cos_beta < 1e-3 ? 0.0 : asin(clamp(by / cos_beta, -1.0, 1.0));
  beta = clamp(degrees(beta), -90.0, 90.0);
  alpha = clamp(degrees(alpha), -90.0, 90.0);

  int ib, ia, it, ip;
  float wb, wa, wt, wp;
  if (itab(H_COS_BETA) != 0) {
    ib = clamp(int((sin(radians(beta)) + 1.0) * 0.5 * float(n_beta - 1)), 0, n_beta - 2);
    float b0 = ftab(itab(H_F_BETA) + ib), b1 = ftab(itab(H_F_BETA) + ib + 1);
    wb = (beta - b0) / (b1 - b0);
  }
  else {
    mlvq_uniform_index(beta + 90.0, 180.0 / float(n_beta - 1), n_beta - 2, ib, wb);
  }
  mlvq_uniform_index(alpha + 90.0, 180.0 / float(n_alpha - 1), n_alpha - 2, ia, wa);
  mlvq_uniform_index(clamp(theta_v, 0.0, 90.0), 90.0 / float(n_theta - 1), n_theta - 2, it, wt);
  mlvq_uniform_index(clamp(view_phi, 0.0, 360.0), 360.0 / float(n_phi), n_phi - 1, ip, wp);

  int texel = y * width + x;
  int slot6 = itab(itab(H_PDF6_SLICES) + texel) - 1;
  if (slot6 < 0) {
    return vec3(0.0);
  }
  vec3 rgb = vec3(0.0);
  for (int k = 0; k < 2; k++) {
    int phi = (k == 1) ? (ip + 1) % n_phi : ip;
    int i4 = slot6 * n_phi + phi;
    int idx3 = itab(itab(H_PDF4_SLICES) + i4);
    float s4 = ftab(itab(H_F_PDF4_SCALE) + i4) * ((k == 1) ? wp : 1.0 - wp);
    for (int j = 0; j < 2; j++) {
      int i3 = idx3 * n_theta + it + j;
      float s3 = ftab(itab(H_F_PDF3_SCALE) + i3) * ((j == 1) ? wt : 1.0 - wt);
      rgb += mlvq_pdf2(itab(itab(H_PDF3_SLICES) + i3), ia, wa, ib, wb, n_beta, n_alpha) *
             (s4 * s3);
    }
  }
  rgb *= ftab(itab(H_F_PDF6_SCALE) + texel);
  if (itab(H_HDR) != 0) {
    rgb /= ftab(F_HDR_VALUE);
  }
  return rgb;
}
