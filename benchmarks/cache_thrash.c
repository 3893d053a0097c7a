// A noisy neighbour for benchmarks/glint_gi_neighbour.py (issue 10, session 45): writes random 64-byte lines of a
// buffer of SIZE_MB (default 64) until killed. usage: cache_thrash [SIZE_MB]. Not part of the build.
#include <stdint.h>
#include <stdlib.h>
int main(int argc, char **argv) {
  size_t mb = argc > 1 ? (size_t)atol(argv[1]) : 64;
  size_t n = mb << 20;
  volatile uint8_t *b = malloc(n);
  if (b == NULL || n < 64) return 1;
  uint64_t x = 88172645463325252ull;
  for (;;) {
    for (size_t i = 0; i < n; i += 64) {
      x ^= x << 13;
      x ^= x >> 7;
      x ^= x << 17;
      b[(x % (n >> 6)) << 6] += 1;  // random lines: defeats the prefetcher
    }
  }
}
