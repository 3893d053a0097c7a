// Polynomial evaluation by Horner's rule, unrolled at compile time.
#pragma once

#include <array>
#include <cstddef>
#include <utility>

namespace glimmer {

// c[0] + x (c[1] + x (... + x c[N-1])): the chain p = c[k] + x p from the
// highest coefficient down, written out in full (no loop left for the
// optimiser to keep), so a fitted polynomial reads as its coefficient list
// and gives the bits of the same chain written by hand.
template <typename T, std::size_t N>
[[gnu::always_inline]] inline T horner(T x, const std::array<T, N> &c) {
  static_assert(N >= 1);
  T p = c[N - 1];
  [&]<std::size_t... K>(std::index_sequence<K...>) { ((p = c[N - 2 - K] + x * p), ...); }
  (std::make_index_sequence<N - 1>());
  return p;
}

}  // namespace glimmer
