// Hashing and random numbers. Everything is a pure function of its inputs, so
// images are identical for any thread count and tile size.
#pragma once

#include <cstdint>

namespace glimmer {

// PCG-style integer hash (Jarzynski & Olano 2020, "Hash Functions for GPU Rendering"). Its three constants are named
// once: the lane forms (glint's row keys) and WalkRng use them too.
inline constexpr uint32_t kPcgMultiplier = 747796405u, kPcgIncrement = 2891336453u, kPcgOutputMultiplier = 277803737u;
constexpr uint32_t hash_u32(uint32_t v) {
  const uint32_t state = v * kPcgMultiplier + kPcgIncrement;
  const uint32_t word = ((state >> ((state >> 28u) + 4u)) ^ state) * kPcgOutputMultiplier;
  return (word >> 22u) ^ word;
}
constexpr uint32_t hash_combine(uint32_t seed, uint32_t v) { return hash_u32(seed ^ (v + 0x9e3779b9u + (seed << 6) + (seed >> 2))); }
constexpr uint32_t hash_u32x2(uint32_t a, uint32_t b) { return hash_combine(hash_u32(a), b); }
constexpr uint32_t hash_u32x3(uint32_t a, uint32_t b, uint32_t c) { return hash_combine(hash_u32x2(a, b), c); }
constexpr uint32_t hash_u32x4(uint32_t a, uint32_t b, uint32_t c, uint32_t d) {
  return hash_combine(hash_u32x3(a, b, c), d);
}

// Tiny Encryption Algorithm with a configurable number of rounds (Zafar et
// al. 2010 use it as a GPU random number generator; Wang 2018 uses 8 rounds
// seeded by the hierarchy node id).
template <int Rounds = 8>
constexpr void tea(uint32_t &v0, uint32_t &v1) {
  uint32_t sum = 0u;
  for (int i = 0; i < Rounds; ++i) {
    sum += 0x9e3779b9u;
    v0 += ((v1 << 4) + 0xa341316cu) ^ (v1 + sum) ^ ((v1 >> 5) + 0xc8013ea4u);
    v1 += ((v0 << 4) + 0xad90777du) ^ (v0 + sum) ^ ((v0 >> 5) + 0x7e95761eu);
  }
}

// Uniform float in [0, 1) from the top 24 bits.
constexpr float uint_to_unit_float(uint32_t v) { return static_cast<float>(v >> 8) * (1.0f / 16777216.0f); }
// Uniform double in [0, 1) from 53 bits of two words.
constexpr double uint2_to_unit_double(uint32_t hi, uint32_t lo) {
  return static_cast<double>((static_cast<uint64_t>(hi) << 21) ^ (lo >> 11)) * (1.0 / 9007199254740992.0);
}

// A small sequential generator (PCG32, O'Neill 2014) for tests, tables and
// precomputation; rendering uses the stateless hashes above.
class Pcg32 {
 public:
  explicit Pcg32(uint64_t seed = 0x853c49e6748fea9bULL, uint64_t stream = 0xda3e39cb94b95bdbULL) {
    state_ = 0u;
    inc_ = (stream << 1u) | 1u;
    next_u32();
    state_ += seed;
    next_u32();
  }
  uint32_t next_u32() {
    const uint64_t old = state_;
    state_ = old * 6364136223846793005ULL + inc_;
    const uint32_t xorshifted = static_cast<uint32_t>(((old >> 18u) ^ old) >> 27u);
    const uint32_t rot = static_cast<uint32_t>(old >> 59u);
    return (xorshifted >> rot) | (xorshifted << ((~rot + 1u) & 31u));
  }
  float next_float() { return uint_to_unit_float(next_u32()); }
  double next_double() {
    const uint32_t hi = next_u32();
    return uint2_to_unit_double(hi, next_u32());
  }

 private:
  uint64_t state_;
  uint64_t inc_;
};

}  // namespace glimmer
