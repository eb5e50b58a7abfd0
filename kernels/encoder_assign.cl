// Nearest codeword for the MLVQ encoder (btf_addon/cl/encoder_assign.py; numpy twin:
// core/encoders/kmeans.py nearest).
//
// One work-item per data row. Score of row x against codeword c: <x, w_c> + bias_c, with
//   plain:      w = c, bias = -|c|^2 / 2        (argmax = the Euclidean nearest codeword)
//   scale-free: w = c / |c|, bias = 0, score clamped at 0 (argmax = best non-negative scale)
// prepared on the host. Ties: the lowest index wins (strict >), as numpy's argmax.
//
// Codewords are walked in tiles of ASSIGN_TK; for each tile the dimensions in slices of
// ASSIGN_TD are staged in local memory (shared by the work-group) and each work-item keeps
// ASSIGN_TK partial sums in registers. x arrives dimension-major (xt[d * n + row]) so that
// neighbouring work-items read neighbouring addresses.

#ifndef ASSIGN_TK
#define ASSIGN_TK 16
#endif
#ifndef ASSIGN_TD
#define ASSIGN_TD 64
#endif

__kernel void assign_nearest(__global const float *xt,   // (d, n) float32
                             __global const float *w,    // (k, d) float32
                             __global const float *bias, // (k,) float32
                             const int n, const int k, const int d, const int clamp_zero,
                             __global int *labels)       // (n,) int32
{
    __local float tile[ASSIGN_TK * ASSIGN_TD];
    const int row = get_global_id(0);
    const int lid = get_local_id(0);
    const int lsz = get_local_size(0);
    const bool live = row < n;
    float best = -INFINITY;
    int best_i = 0;
    for (int c0 = 0; c0 < k; c0 += ASSIGN_TK) {
        float acc[ASSIGN_TK];
        for (int j = 0; j < ASSIGN_TK; ++j)
            acc[j] = 0.0f;
        for (int d0 = 0; d0 < d; d0 += ASSIGN_TD) {
            barrier(CLK_LOCAL_MEM_FENCE);
            for (int t = lid; t < ASSIGN_TK * ASSIGN_TD; t += lsz) {
                const int j = t / ASSIGN_TD, dd = t % ASSIGN_TD;
                const int c = c0 + j, e = d0 + dd;
                tile[t] = (c < k && e < d) ? w[(size_t)c * d + e] : 0.0f;
            }
            barrier(CLK_LOCAL_MEM_FENCE);
            if (live) {
                const int span = min(ASSIGN_TD, d - d0);
                for (int dd = 0; dd < span; ++dd) {
                    const float xv = xt[(size_t)(d0 + dd) * n + row];
                    for (int j = 0; j < ASSIGN_TK; ++j)
                        acc[j] = fma(xv, tile[j * ASSIGN_TD + dd], acc[j]);
                }
            }
        }
        for (int j = 0; j < ASSIGN_TK && c0 + j < k; ++j) {
            float s = acc[j] + bias[c0 + j];
            if (clamp_zero)
                s = fmax(s, 0.0f);
            if (s > best) {
                best = s;
                best_i = c0 + j;
            }
        }
    }
    if (live)
        labels[row] = best_i;
}
