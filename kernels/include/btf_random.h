/* Per-pixel random numbers for the Monte Carlo paths (PCG hash, O'Neill 2014). */
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

#endif
