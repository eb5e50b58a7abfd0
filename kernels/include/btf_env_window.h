#ifndef BTF_ENV_WINDOW_H
#define BTF_ENV_WINDOW_H
/* The lobe window: the environment's next-event table restricted to a latitude-longitude
 * window around a glossy lobe's mirror direction (render_direct.cl "1c."). Neither the whole
 * map's draws nor the lobe's own find the light a narrow lobe reflects from a large patchy
 * source (forest.exr's sun through leaves: 80 % of its light above the mean in 6 % of the map,
 * bright and dark pixels side by side): most of the map's draws land outside the lobe, and the
 * lobe's land on bright and dark pixels alike. Drawn in proportion to the map inside the
 * window, the draws land in the lobe on the bright pixels.
 *
 * The window is a rectangle of blocks of the block map (envmap.py LobeWindowTable: each row of
 * blocks' probability and CDF): rows around the mirror's elevation ± rho, columns wide enough
 * for the spherical cap of radius rho at the window's widest row (the whole row where the cap
 * reaches a pole). A draw picks a block by the window's sums, then a pixel in it by the
 * table's own probabilities, so a pixel's probability is its table probability over the
 * window's: its density is the table's density / mass, inside the window, and 0 outside.
 * Included by render_direct.cl after env_map_vector, env_direction, table_density and
 * cdf_search. */

/* Rows of blocks a window may span (its sums live in the kernel's private memory): rho is
 * clamped to fit, so with envmap.py WINDOW_BLOCK_ROWS = 128 a window is at most 45° tall. */
#define WINDOW_ROWS 32
/* The largest block (envmap.py WINDOW_MAX_BLOCK: a map more than 8192 pixels tall draws no
 * window): a drawn block's row sums live in private memory too. */
#define WINDOW_BLOCK_MAX 64

typedef struct {
  int row0, rows;            /* rows of blocks row0 .. row0 + rows − 1 */
  int col0, cols;            /* columns of blocks col0 .. col0 + cols − 1, modulo the row */
  float mass;                /* the table's probability inside (0: nothing to draw) */
  float sums[WINDOW_ROWS];   /* each row's share of it */
} LobeWindow;

/* The probability of blocks [c0, c0 + n) of a row of blocks, wrapping around its end. */
inline float block_span(__global const float *cdf, int cols, int c0, int n)
{
  int c1 = c0 + n;
  if (c1 <= cols) {
    return cdf[c1] - cdf[c0];
  }
  return (cdf[cols] - cdf[c0]) + cdf[c1 - cols];
}

/* The window around `mirror` (world) for a GGX lobe of roughness `alpha`, and its sums. Its
 * angular radius rho is twice the half-vector angle whose tangent is alpha, inside which a GGX
 * lobe's reflection holds half its light (tan² θh is distributed as x / (α² + x)); of 0.5–1.5×
 * that radius this one measured best on the demo (docs/accuracy.md, "The lobe window"). Any
 * window is unbiased: its size only moves the noise. Every angle through btf_atan2 (the
 * decode's polynomial, btf_packed.h), the rest from the half-angle formulas (cos rho, sin rho
 * of tan(rho / 2) = alpha) and sums of angles: no library call unless rho is clamped. */
inline LobeWindow lobe_window(float3 mirror, float alpha, __global const float *block_row_pdf,
                              __global const float *block_cdf, int block, int w, int h,
                              float rotation)
{
  LobeWindow win;
  int rows = (h + block - 1) / block, cols = (w + block - 1) / block;
  /* the map point of the mirror, as env_pdf finds it */
  float3 m = env_map_vector(mirror, rotation);
  float s = btf_mod(env_map_s(m), 1.0f);
  float z = clamp(m.z, -1.0f, 1.0f);
  float sin_theta = sqrt(fmax((1.0f - z) * (1.0f + z), 0.0f));
  float theta = btf_atan2(sin_theta, z);
  float rows_per_radian = (float)rows / M_PI_F;
  float a2 = alpha * alpha;
  float rho = 2.0f * btf_atan2(alpha, 1.0f), cos_rho = (1.0f - a2) / (1.0f + a2);
  float sin_rho = 2.0f * alpha / (1.0f + a2);
  float most = 0.5f * (float)(WINDOW_ROWS - 1) / rows_per_radian; /* the rows that fit */
  if (rho > most) {
    rho = most;
    sin_rho = sin(most);
    cos_rho = cos(most);
  }
  float t0 = theta - rho, t1 = theta + rho;
  win.row0 = clamp((int)(t0 * rows_per_radian), 0, rows - 1);
  win.rows = min(clamp((int)(t1 * rows_per_radian), 0, rows - 1) - win.row0 + 1, WINDOW_ROWS);
  /* the cap's longitude extent is asin(sin rho / sin theta) at colatitude theta: widest at
   * the window's row nearest a pole, the whole row where the cap holds a pole */
  float sin_t0 = sin_theta * cos_rho - z * sin_rho, sin_t1 = sin_theta * cos_rho + z * sin_rho;
  float sin_edge = (t0 <= 0.0f || t1 >= M_PI_F) ? 0.0f : fmin(sin_t0, sin_t1);
  win.col0 = 0;
  win.cols = cols;
  if (sin_rho < sin_edge) {
    float x = sin_rho / sin_edge; /* asin x = atan2(x, √(1 − x²)) */
    float half_width = btf_atan2(x, sqrt(fmax(1.0f - x * x, 0.0f))) / (2.0f * M_PI_F); /* in s */
    int c0 = (int)floor((s - half_width) * cols), c1 = (int)floor((s + half_width) * cols);
    if (c1 - c0 + 1 < cols) {
      win.col0 = c0 < 0 ? c0 + cols : c0;
      win.cols = c1 - c0 + 1;
    }
  }
  float mass = 0.0f;
  for (int r = 0; r < win.rows; r++) {
    int row = win.row0 + r;
    win.sums[r] = block_row_pdf[row] *
                  fmax(block_span(block_cdf + row * (cols + 1), cols, win.col0, win.cols), 0.0f);
    mass += win.sums[r];
  }
  win.mass = mass;
  return win;
}

/* Whether map pixel `pixel` lies in the window. */
inline bool in_lobe_window(const LobeWindow *win, int block, int w, int h, int pixel)
{
  int cols = (w + block - 1) / block;
  int row = pixel / w;
  int r = row / block - win->row0, c = (pixel - row * w) / block - win->col0;
  c = c < 0 ? c + cols : c;
  return r >= 0 && r < win->rows && c < win->cols;
}

/* The window's density at a pixel of table density `table` (0 outside, or without a window). */
inline float lobe_window_density(const LobeWindow *win, int block, int w, int h, int pixel,
                                 float table)
{
  return win->mass > 0.0f && in_lobe_window(win, block, w, h, pixel) ? table / win->mass : 0.0f;
}

/* A point of the window for uniform u: a row of blocks by the sums, a block in it by the
 * block CDF, then a pixel of the block by the table (a row by its probability within the
 * block's columns, a column by the row's CDF), the point uniformly in the pixel. */
inline float3 lobe_window_draw(const LobeWindow *win, float2 u, __global const float *block_cdf,
                               __global const float *row_pdf, __global const float *col_cdf,
                               int block, int w, int h, float rotation, int *pixel,
                               float *sin_t)
{
  int cols = (w + block - 1) / block;
  /* the row of blocks */
  float target = u.x * win->mass;
  int r = 0;
  while (r < win->rows - 1 && target >= win->sums[r]) {
    target -= win->sums[r];
    r++;
  }
  float v = clamp(target / fmax(win->sums[r], 1e-30f), 0.0f, 0.999999f);
  int block_row = win->row0 + r;
  /* the block: the window's columns of this row, through its CDF (in two pieces where they
   * wrap around the row's end) */
  __global const float *bc = block_cdf + block_row * (cols + 1);
  int a0 = win->col0, a1 = min(win->col0 + win->cols, cols);
  int b1 = win->col0 + win->cols - a1; /* the wrapped piece is blocks [0, b1) */
  float first = bc[a1] - bc[a0], span = first + (bc[b1] - bc[0]);
  float x = u.y * span;
  bool wrapped = b1 > 0 && !(x < first);
  float at = wrapped ? bc[0] + (x - first) : bc[a0] + x;
  /* kept inside the window's piece: rounding can put `at` on the piece's last CDF value,
   * which the search may answer with a block past it (the density would not match) */
  int block_col = wrapped ? clamp(cdf_search(bc, cols, at), 0, b1 - 1)
                          : clamp(cdf_search(bc, cols, at), a0, a1 - 1);
  /* the pixel: a row of the block by its probability in the block's columns… */
  int row0 = block_row * block, rows_in = min(block, h - row0);
  int col0 = block_col * block, col1 = min(col0 + block, w);
  float row_mass[WINDOW_BLOCK_MAX];
  float total = 0.0f;
  for (int k = 0; k < rows_in; k++) {
    __global const float *cc = col_cdf + (row0 + k) * (w + 1);
    row_mass[k] = row_pdf[row0 + k] * fmax(cc[col1] - cc[col0], 0.0f);
    total += row_mass[k];
  }
  float y = v * total;
  int k = 0;
  while (k < rows_in - 1 && y >= row_mass[k]) {
    y -= row_mass[k];
    k++;
  }
  float dt = clamp(y / fmax(row_mass[k], 1e-30f), 0.0f, 0.999999f);
  int row = row0 + k;
  /* …and a column by the row's CDF within them (the block's own share of u.y again) */
  __global const float *cc = col_cdf + row * (w + 1);
  float within = (at - bc[block_col]) / fmax(bc[block_col + 1] - bc[block_col], 1e-30f);
  float c = cc[col0] + clamp(within, 0.0f, 0.999999f) * (cc[col1] - cc[col0]);
  int col = clamp(cdf_search(cc, w, c), col0, col1 - 1);
  float ds = (c - cc[col]) / fmax(cc[col + 1] - cc[col], 1e-30f);
  *pixel = row * w + col;
  return env_direction((col + clamp(ds, 0.0f, 0.999999f)) / w, (row + dt) / h, rotation, sin_t);
}

#endif
