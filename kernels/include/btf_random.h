/* Random numbers for the Monte Carlo paths.
 *
 * pcg_hash / rand01: a hash-based generator (O'Neill 2014) for decisions that need no
 * stratification (Russian roulette). Sampler / next_2d: the first two Sobol dimensions with
 * hash-based Owen scrambling and a per-dimension shuffle of the sample order (Burley 2020,
 * "Practical Hash-based Owen Scrambling"): every 2D decision of a path (environment sample,
 * light sample, direction sample at each vertex) gets its own randomised (0, 2)-sequence, so the
 * first 2^k samples of a pixel stratify each of them, and the error falls faster than with
 * independent random numbers while staying unbiased. */
#ifndef BTF_RANDOM_H
#define BTF_RANDOM_H

inline uint pcg_hash(uint v)
{
  uint state = v * 747796405u + 2891336453u;
  uint word = ((state >> ((state >> 28u) + 4u)) ^ state) * 277803737u;
  return (word >> 22u) ^ word;
}

inline float rand01(uint *state)
{
  *state = pcg_hash(*state);
  return (float)(*state >> 8) * (1.0f / 16777216.0f);
}

inline uint reverse_bits(uint x)
{
  x = ((x >> 1) & 0x55555555u) | ((x & 0x55555555u) << 1);
  x = ((x >> 2) & 0x33333333u) | ((x & 0x33333333u) << 2);
  x = ((x >> 4) & 0x0F0F0F0Fu) | ((x & 0x0F0F0F0Fu) << 4);
  x = ((x >> 8) & 0x00FF00FFu) | ((x & 0x00FF00FFu) << 8);
  return (x >> 16) | (x << 16);
}

/* Owen scrambling of a 32-bit fraction: a hash that only lets higher bits affect lower ones,
 * applied in reversed-bit order. */
inline uint owen_hash(uint x, uint seed) /* on the bit-reversed fraction */
{
  x += seed;
  x ^= x * 0x6c50b47cu;
  x ^= x * 0xb82f1e52u;
  x ^= x * 0xc7afe638u;
  x ^= x * 0x8d22f6e6u;
  return x;
}

inline uint owen_scramble(uint x, uint seed)
{
  return reverse_bits(owen_hash(reverse_bits(x), seed));
}

/* Sobol's second dimension (the first is the bit-reversed index), bit-reversed: the order
 * owen_hash works in. reverse_bits(v >> 1) = reverse_bits(v) << 1, so the generator's columns
 * v ^= v >> 1 from 1 << 31 become v ^= v << 1 from 1. */
inline uint sobol_dim1_reversed(uint index)
{
  uint result = 0u, v = 1u;
  for (; index; index >>= 1, v ^= v << 1) {
    if (index & 1u) {
      result ^= v;
    }
  }
  return result;
}

typedef struct {
  uint pixel; /* hashed pixel and render seed */
  uint index; /* sample number within the pixel */
  uint dim;   /* 2D decisions taken so far on this path */
  uint rng;   /* for rand01 */
} Sampler;

inline float2 next_2d(Sampler *s)
{
  uint seed = pcg_hash(s->pixel ^ pcg_hash(s->dim++ * 0x9E3779B9u + 0x632BE5ABu));
  uint i = owen_scramble(s->index, seed); /* shuffled order: decorrelates the dimensions */
  /* owen_scramble(sobol point, k) for both dimensions, the point taken in the bit-reversed
   * order owen_hash works in: Sobol's first dimension reversed is i itself, so the two
   * reversals around each hash's input cancel (next_2d was 14 % of a Lambertian sample). */
  uint x = reverse_bits(owen_hash(i, pcg_hash(seed ^ 0xA511E9B3u)));
  uint y = reverse_bits(owen_hash(sobol_dim1_reversed(i), pcg_hash(seed ^ 0x63D83595u)));
  return (float2)((float)(x >> 8), (float)(y >> 8)) * (1.0f / 16777216.0f);
}

#endif
