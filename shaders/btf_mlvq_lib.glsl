/* BTFbase MLVQ decoding in GLSL: the same steps as btf_addon/core/codecs/mlvq.py (the reference, which
 * documents each level) and kernels/include/btf_packed.h. Needs btf_tables_lib, btf_colour_lib. */

/* Laid out as kernels/include/btf_packed.h reads it: the interleaved tables f_mlvq*
 * (btf_addon/core/codecs/packed.py mlvq_fast_tables; f_mlvq43 resolves pdf4 → pdf3), the Hermite step's weights and the colour
 * curves' β weights once per decode; β and α by atan from the turned light vector (accurate at
 * grazing light, where asin in float32 is not). */

/* mlvq_pdf1's Hermite step (core/codecs/mlvq.py _pdf1) as weights on p[i-1], p[i], p[i+1]. */
vec3 mlvq_hermite_weights(int i, float w, int n_beta)
{
  float t2 = w * w, t3 = t2 * w;
  float h01 = -2.0 * t3 + 3.0 * t2;
  float h00 = 1.0 - h01;
  float h11 = t3 - t2;
  float h10 = h11 - t2 + w;
  float gm = (i == n_beta - 2) ? 1.0 : 0.5;
  if (i == 0) { /* m0 = p1 - p0 */
    return vec3(0.0, h00 - h10 - gm * h11, h01 + h10 + gm * h11);
  }
  return vec3(-0.5 * h10, h00 - gm * h11, h01 + 0.5 * h10 + gm * h11);
}

float mlvq_curve(int s, int ib, vec3 hw, int n_beta)
{
  int at = itab(H_F_PDF1) + s * n_beta + ib - 1; /* the header precedes: at - 1 stays inside */
  return hw.x * ftab(at) + hw.y * ftab(at + 1) + hw.z * ftab(at + 2);
}

vec2 mlvq_cbcr(int c, int ib, float wb, int n_beta)
{
  int at = itab(H_F_MLVQ_AB) + 2 * (c * n_beta + ib);
  return vec2(ftab(at), ftab(at + 1)) * (1.0 - wb) + vec2(ftab(at + 2), ftab(at + 3)) * wb;
}

/* One 2D function at (α, β) from its f_mlvq43 entry (luminance fn, colour fn). */
vec3 mlvq_pdf2(int lum_fn, int col_fn, int ia, float wa, int ib, float wb, vec3 hw, int n_beta,
               int n_alpha)
{
  int f2 = itab(H_F_MLVQ2) + 2 * (lum_fn * n_alpha + ia); /* (scale, curve) pairs */
  float lum = (1.0 - wa) * ftab(f2) * mlvq_curve(int(ftab(f2 + 1)), ib, hw, n_beta) +
              wa * ftab(f2 + 2) * mlvq_curve(int(ftab(f2 + 3)), ib, hw, n_beta);
  int ci = itab(H_PDF2_COLOURS) + col_fn * n_alpha + ia;
  vec2 cbcr = (1.0 - wa) * mlvq_cbcr(itab(ci), ib, wb, n_beta) +
              wa * mlvq_cbcr(itab(ci + 1), ib, wb, n_beta);
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
  float bx = clamp(cos(ph) * sin(th), -1.0, 1.0), by = sin(ph) * sin(th), bz = cos(th);
  float cos_beta = sqrt(by * by + bz * bz); /* no cancellation, unlike sqrt(1 - bx²) */
  float beta = clamp(degrees(atan(bx, cos_beta)), -90.0, 90.0);
  float alpha = cos_beta < 1e-3 ? 0.0 : clamp(degrees(atan(by, max(bz, 0.0))), -90.0, 90.0);

  int ib, ia, it, ip;
  float wb, wa, wt, wp;
  if (itab(H_COS_BETA) != 0) {
    ib = clamp(int((bx + 1.0) * 0.5 * float(n_beta - 1)), 0, n_beta - 2);
    float b0 = ftab(itab(H_F_BETA) + ib), b1 = ftab(itab(H_F_BETA) + ib + 1);
    wb = (beta - b0) / (b1 - b0);
  }
  else {
    mlvq_uniform_index(beta + 90.0, 180.0 / float(n_beta - 1), n_beta - 2, ib, wb);
  }
  mlvq_uniform_index(alpha + 90.0, 180.0 / float(n_alpha - 1), n_alpha - 2, ia, wa);
  mlvq_uniform_index(clamp(theta_v, 0.0, 90.0), 90.0 / float(n_theta - 1), n_theta - 2, it, wt);
  mlvq_uniform_index(clamp(view_phi, 0.0, 360.0), 360.0 / float(n_phi), n_phi - 1, ip, wp);

  vec3 hw = mlvq_hermite_weights(ib, wb, n_beta);
  int f6 = itab(H_F_MLVQ6) + 2 * (y * width + x); /* (pdf6 scale, slot + 1) */
  int slot6 = int(ftab(f6 + 1)) - 1;
  if (slot6 < 0) {
    return vec3(0.0);
  }
  vec3 rgb = vec3(0.0);
  for (int k = 0; k < 2; k++) {
    int phi = (k == 1) ? (ip + 1) % n_phi : ip;
    float wk = (k == 1) ? wp : 1.0 - wp;
    for (int j = 0; j < 2; j++) {
      /* f_mlvq43: (s4·s3, luminance fn, colour fn, 0) per (slot, φ, θ), pdf4 → pdf3 resolved */
      int f43 = itab(H_F_MLVQ43) + 4 * ((slot6 * n_phi + phi) * n_theta + it + j);
      float w43 = ftab(f43) * (wk * ((j == 1) ? wt : 1.0 - wt));
      rgb += mlvq_pdf2(int(ftab(f43 + 1)), int(ftab(f43 + 2)), ia, wa, ib, wb, hw, n_beta,
                       n_alpha) *
             w43;
    }
  }
  rgb *= ftab(f6);
  if (itab(H_HDR) != 0) {
    rgb /= ftab(F_HDR_VALUE);
  }
  return rgb;
}
