/* Which pixel of a launch's band a work-item renders.
 *
 * A CPU driver hands its threads contiguous runs of work-groups in index order (PoCL: each
 * thread takes the next run of the remaining ones). A band's rows differ in cost by orders of
 * magnitude (sky against a BTF under four bounces), so runs of sky rows and runs of object rows
 * landed on different cores and one waited for the other: on 2 cores the demo's 1024 samples
 * took 1.34 s in whole-image launches and 0.88 s in launches of 2 rows
 * (docs/accuracy.md, "Final render against Cycles"). Here the work-group index goes through a
 * multiplicative permutation (k -> k * m mod groups, m coprime to the count, near its golden
 * section), so every run of consecutive groups is spread over the whole band and each thread
 * gets a fair share of every kind of row: 0.83 s for those 1024 samples in whole-image
 * launches. A bijection: every pixel is rendered once, and what a pixel renders depends only
 * on its own coordinates and samples, so the image is the one of before up to float rounding
 * (the compiler vectorises the loop differently: at most 2e-6 on the demo). */

inline int launch_gcd(int a, int b)
{
  while (b != 0) {
    int r = a % b;
    a = b;
    b = r;
  }
  return a;
}

/* x and the row inside the band (yr) of this work-item, for a 2D launch whose work-groups are
 * (local size, 1) and cover (global width, rows). */
inline void launch_pixel(int *x, int *yr)
{
  int groups_x = (int)get_num_groups(0);
  int groups = groups_x * (int)get_num_groups(1);
  int m = max((int)(0.618034f * (float)groups), 1);
  while (launch_gcd(m, groups) != 1) {
    m++;
  }
  int k = (int)get_group_id(0) + groups_x * (int)get_group_id(1);
  int j = (int)(((long)k * (long)m) % (long)groups);
  *x = (j % groups_x) * (int)get_local_size(0) + (int)get_local_id(0);
  *yr = j / groups_x;
}
