/* BTFbase MLVQ decoding on the device: the same steps as btf_addon/core/mlvq.py (the reference,
 * which documents each level). Table layouts: row-major, one row per function. */
#ifndef BTF_MLVQ_H
#define BTF_MLVQ_H

#include "btf_colour.h"

typedef struct {
  __global const float *pdf1;         /* (n1, n_beta) */
  __global const float *ab_colors;    /* (nc, 2) */
  __global const int *index_ab;       /* (niab, n_beta) */
  __global const int *pdf2_colours;   /* (n2c, n_alpha) */
  __global const int *pdf2_slices;    /* (n2l, n_alpha) */
  __global const float *pdf2_scale;   /* (n2l, n_alpha) */
  __global const int *pdf2_indices;   /* (n2, 2) */
  __global const int *pdf3_slices;    /* (n3, n_theta) */
  __global const float *pdf3_scale;   /* (n3, n_theta) */
  __global const int *pdf4_slices;    /* (n4, n_phi) */
  __global const float *pdf4_scale;   /* (n4, n_phi) */
  __global const int *pdf6_slices;    /* (height, width), 1-based, 0 = not stored */
  __global const float *pdf6_scale;   /* (height, width) */
  __global const float *beta_angles;  /* (n_beta,) degrees */
  int n_beta, n_alpha, n_theta, n_phi, width, height, rows_offset, cols_offset;
  float hdr_value;
} MLVQTables;

/* Cubic Hermite at P1 with the original decoder's tangents. */
inline float mlvq_pdf1(const MLVQTables *t, int s, int i, float w)
{
  __global const float *row = t->pdf1 + s * t->n_beta;
  float p0 = row[i], p1 = row[i + 1];
  float m0 = (i == 0) ? p1 - p0 : 0.5f * (p1 - row[i - 1]);
  float m1 = (i == t->n_beta - 2) ? p1 - p0 : 0.5f * (p1 - p0);
  float t2 = w * w, t3 = t2 * w;
  float h01 = -2.0f * t3 + 3.0f * t2;
  float h00 = 1.0f - h01;
  float h11 = t3 - t2;
  float h10 = h11 - t2 + w;
  return h00 * p0 + h10 * m0 + h01 * p1 + h11 * m1;
}

inline float2 mlvq_ab(const MLVQTables *t, int c, int i, float w)
{
  __global const int *row = t->index_ab + c * t->n_beta;
  float2 a = vload2(row[i], t->ab_colors);
  float2 b = vload2(row[i + 1], t->ab_colors);
  return a * (1.0f - w) + b * w;
}

inline float3 mlvq_pdf2(const MLVQTables *t, int idx2, int ia, float wa, int ib, float wb)
{
  int lum_fn = t->pdf2_indices[2 * idx2];
  int col_fn = t->pdf2_indices[2 * idx2 + 1];
  float lum = 0.0f;
  float2 cbcr = (float2)(0.0f);
  for (int k = 0; k < 2; k++) {
    int a = ia + k;
    float w = k ? wa : 1.0f - wa;
    int li = lum_fn * t->n_alpha + a;
    lum += w * t->pdf2_scale[li] * mlvq_pdf1(t, t->pdf2_slices[li], ib, wb);
    cbcr += w * mlvq_ab(t, t->pdf2_colours[col_fn * t->n_alpha + a], ib, wb);
  }
#if MLVQ_HDR
  return btf_logluv_to_rgb(lum, cbcr.x, cbcr.y);
#else
  return btf_ycbcr_to_rgb(lum, cbcr.x, cbcr.y);
#endif
}

inline void uniform_index(float x, float step, int max_index, int *i, float *w)
{
  int k = clamp((int)(x / step), 0, max_index);
  *i = k;
  *w = (x - k * step) / step;
}

inline float positive_mod(float x, float m)
{
  return x - m * floor(x / m);
}

/* Angles in degrees (theta <= 90, already canonical); returns the decoder's raw RGB. */
inline float3 mlvq_decode(const MLVQTables *t, float u, float v, float theta_i, float phi_i,
                          float theta_v, float phi_v)
{
  int x = ((int)floor(positive_mod(u, 1.0f) * t->width) - t->cols_offset) % t->width;
  int y = ((int)floor(positive_mod(v, 1.0f) * t->height) - t->rows_offset) % t->height;
  x = (x + t->width) % t->width;
  y = (y + t->height) % t->height;

  float view_phi = positive_mod(360.0f - phi_v, 360.0f);
  float light_phi = positive_mod((360.0f - phi_i) - (90.0f + view_phi), 360.0f);
  float th = radians(theta_i), ph = radians(light_phi);
  float bx = cos(ph) * sin(th), by = sin(ph) * sin(th);
  float beta = asin(clamp(bx, -1.0f, 1.0f));
  float cos_beta = cos(beta);
  float alpha = cos_beta < 1e-3f ? 0.0f : asin(clamp(by / cos_beta, -1.0f, 1.0f));
  beta = clamp(degrees(beta), -90.0f, 90.0f);
  alpha = clamp(degrees(alpha), -90.0f, 90.0f);

  int ib;
  float wb;
#if MLVQ_COS_BETA
  ib = clamp((int)((sin(radians(beta)) + 1.0f) * 0.5f * (t->n_beta - 1)), 0, t->n_beta - 2);
  wb = (beta - t->beta_angles[ib]) / (t->beta_angles[ib + 1] - t->beta_angles[ib]);
#else
  uniform_index(beta + 90.0f, 180.0f / (t->n_beta - 1), t->n_beta - 2, &ib, &wb);
#endif
  int ia, it, ip;
  float wa, wt, wp;
  uniform_index(alpha + 90.0f, 180.0f / (t->n_alpha - 1), t->n_alpha - 2, &ia, &wa);
  uniform_index(clamp(theta_v, 0.0f, 90.0f), 90.0f / (t->n_theta - 1), t->n_theta - 2, &it, &wt);
  uniform_index(clamp(view_phi, 0.0f, 360.0f), 360.0f / t->n_phi, t->n_phi - 1, &ip, &wp);

  int texel = y * t->width + x;
  int slot6 = t->pdf6_slices[texel] - 1;
  if (slot6 < 0) {
    return (float3)(0.0f);
  }
  float3 rgb = (float3)(0.0f);
  for (int k = 0; k < 2; k++) {
    int phi = k ? (ip + 1) % t->n_phi : ip;
    int i4 = slot6 * t->n_phi + phi;
    int idx3 = t->pdf4_slices[i4];
    float s4 = t->pdf4_scale[i4] * (k ? wp : 1.0f - wp);
    for (int j = 0; j < 2; j++) {
      int i3 = idx3 * t->n_theta + it + j;
      float s3 = t->pdf3_scale[i3] * (j ? wt : 1.0f - wt);
      rgb += mlvq_pdf2(t, t->pdf3_slices[i3], ia, wa, ib, wb) * (s4 * s3);
    }
  }
  rgb *= t->pdf6_scale[texel];
#if MLVQ_HDR
  rgb /= t->hdr_value;
#endif
  return rgb;
}

#endif
