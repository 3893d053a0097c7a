// Integer constants for vector code, read from memory: a table of rows, each row one constant in every 32-bit lane
// of a 128-bit (Lanes4) or 256-bit (Lanes8) register. GCC builds a _mm*_set1_epi32 of a constant from an immediate
// in three instructions (MOV, VMOVD, VPSHUFD / VPBROADCASTD); a row loaded from the table is one load, or the memory
// operand of the instruction that uses it (VPMULLD, VPXOR, VPADDD). opaque() passes the table's address through an
// empty asm, so GCC neither folds the loads back to immediates nor, where it is applied per step, hoists them.
// Used by the sampler's vector draws (bridge/render/sampler_draw.cpp) and glint's walks (plugin/tables/glint_particles.h).
#pragma once

#include <cstdint>

namespace glimmer {

struct alignas(32) Lanes8 {
  uint32_t lane[8];
};
struct alignas(16) Lanes4 {
  uint32_t lane[4];
};
constexpr Lanes8 lanes8(uint32_t c) { return {{c, c, c, c, c, c, c, c}}; }
constexpr Lanes4 lanes4(uint32_t c) { return {{c, c, c, c}}; }

// p, hidden from the optimiser (the table's contents are not constant-folded through it).
template <typename T>
[[gnu::always_inline]] inline const T *opaque(const T *p) {
  __asm__("" : "+r"(p));
  return p;
}

}  // namespace glimmer
