// The path tracer's sample numbers (internal to render/): padded Owen-scrambled
// Sobol points (Burley 2020, "Practical Hash-based Owen Scrambling").
//
// Every draw is a pure function of (seed, pixel, sample index, dimension), so a
// pixel's samples are bit-identical however they are split into passes or
// spread over threads. Each 1D or 2D draw is its own dimension: the first two
// Sobol dimensions (a (0,2)-sequence), Owen-scrambled by a hash of the
// dimension and the pixel, and taken in an order shuffled by a nested uniform
// scramble of the sample index. A power-of-two prefix of a pixel's samples is
// then a stratified (0,m,2)-net in every 2D draw (the light's two numbers, the
// BSDF's direction), and different draws stay uncorrelated.
//
// A sampler is a small value: copying it copies its place in the path, which
// the differential render uses to trace both worlds with the same numbers.
#pragma once

#include <Eigen/Core>
#include <cstdint>

namespace propcam::render::detail {

inline uint32_t reverse_bits(uint32_t x) {
  x = ((x >> 1) & 0x55555555u) | ((x & 0x55555555u) << 1);
  x = ((x >> 2) & 0x33333333u) | ((x & 0x33333333u) << 2);
  x = ((x >> 4) & 0x0F0F0F0Fu) | ((x & 0x0F0F0F0Fu) << 4);
  x = ((x >> 8) & 0x00FF00FFu) | ((x & 0x00FF00FFu) << 8);
  return (x >> 16) | (x << 16);
}

// A hash in which each bit depends only on the bits below it (Laine and
// Karras' construction, Burley's constants): applied to bit-reversed digits it
// is a nested uniform (Owen) scramble.
inline uint32_t laine_karras_permutation(uint32_t x, uint32_t seed) {
  x += seed;
  x ^= x * 0x6c50b47cu;
  x ^= x * 0xb82f1e52u;
  x ^= x * 0xc7afe638u;
  x ^= x * 0x8d22f6e6u;
  return x;
}

inline uint32_t nested_uniform_scramble(uint32_t x, uint32_t seed) {
  return reverse_bits(laine_karras_permutation(reverse_bits(x), seed));
}

// 32-bit mixing of two words (murmur-style finaliser).
inline uint32_t hash_combine(uint32_t a, uint32_t b) {
  uint32_t h = a ^ (b + 0x9e3779b9u + (a << 6) + (a >> 2));
  h ^= h >> 16;
  h *= 0x7feb352du;
  h ^= h >> 15;
  h *= 0x846ca68bu;
  h ^= h >> 16;
  return h;
}

// The first two Sobol dimensions of point `index`, as 32-bit fractions: the
// van der Corput sequence and the dimension built on the polynomial x + 1.
inline uint32_t sobol_dimension0(uint32_t index) { return reverse_bits(index); }
inline uint32_t sobol_dimension1(uint32_t index) {
  uint32_t result = 0;
  for (uint32_t v = 1u << 31; index != 0; index >>= 1, v ^= v >> 1)
    if (index & 1u) result ^= v;
  return result;
}
// The same with its bits reversed (what a nested scramble works on), built
// from the reversed direction numbers: v_k = 2^k, then v ^= v << 1.
inline uint32_t sobol_dimension1_reversed(uint32_t index) {
  uint32_t result = 0;
  for (uint32_t v = 1u; index != 0; index >>= 1, v ^= v << 1)
    if (index & 1u) result ^= v;
  return result;
}

// A 32-bit fraction as a float in [0, 1): the top 24 bits, exact in a float.
inline float fraction_to_unit(uint32_t bits) { return static_cast<float>(bits >> 8) * 0x1p-24f; }

class SobolSampler {
 public:
  // `pixel_key` tells pixels apart (e.g. y * width + x); `seed` images apart.
  SobolSampler(uint64_t seed, uint64_t pixel_key, uint32_t sample_index)
      : pixel_seed_(hash_combine(hash_combine(static_cast<uint32_t>(seed), static_cast<uint32_t>(seed >> 32)),
                                 hash_combine(static_cast<uint32_t>(pixel_key), static_cast<uint32_t>(pixel_key >> 32)))),
        index_(sample_index) {}

  // nested_uniform_scramble(sobol_dimension0(i), s) and the same of
  // dimension 1, written without the bit reversals that cancel.
  float get1d() {
    const uint32_t key = next_dimension_key();
    const uint32_t shuffled = nested_uniform_scramble(index_, key);
    return fraction_to_unit(reverse_bits(laine_karras_permutation(shuffled, hash_combine(key, 1u))));
  }

  Eigen::Vector2f get2d() {
    const uint32_t key = next_dimension_key();
    const uint32_t shuffled = nested_uniform_scramble(index_, key);
    return {fraction_to_unit(reverse_bits(laine_karras_permutation(shuffled, hash_combine(key, 1u)))),
            fraction_to_unit(
                reverse_bits(laine_karras_permutation(sobol_dimension1_reversed(shuffled), hash_combine(key, 2u))))};
  }

  // The key of the next draw's dimension (tests rebuild draws from it).
  uint32_t peek_dimension_key() const { return hash_combine(pixel_seed_, static_cast<uint32_t>(dimension_)); }

  // Where the next draw starts; the path tracer gives each bounce a fixed range.
  void set_dimension(int dimension) { dimension_ = dimension; }

 private:
  uint32_t next_dimension_key() { return hash_combine(pixel_seed_, static_cast<uint32_t>(dimension_++)); }

  uint32_t pixel_seed_;
  uint32_t index_;
  int dimension_ = 0;
};

}  // namespace propcam::render::detail
