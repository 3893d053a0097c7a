// Does a software prefetch fill cache lines on this machine? (issue 10, docs/history/glints_sessions.md
// "Session 33 (glintprefetch33)")
// Random 64-byte-aligned reads of an array of MB megabytes (malloc: 4 KB pages, so most reads also miss the TLB), each
// followed by W dependent multiplies; mode 0 plain, 1 __builtin_prefetch D reads ahead, 2 a real load D reads ahead.
// Not part of the build: gcc -O2 benchmarks/prefetch_probe.c -o /tmp/prefetch_probe && /tmp/prefetch_probe 64 8 50 1
#include <stdint.h>
#include <stdio.h>
#include <stdlib.h>
#include <time.h>

static double now_seconds(void) {
  struct timespec t;
  clock_gettime(CLOCK_MONOTONIC, &t);
  return (double)t.tv_sec + 1e-9 * (double)t.tv_nsec;
}

int main(int argc, char **argv) {
  const size_t megabytes = argc > 1 ? (size_t)atoi(argv[1]) : 64;
  const int ahead = argc > 2 ? atoi(argv[2]) : 8, work = argc > 3 ? atoi(argv[3]) : 50;
  const int mode = argc > 4 ? atoi(argv[4]) : 0;
  const size_t n = megabytes * 1024 * 1024 / 4, reads = (size_t)1 << 20;
  uint32_t *a = malloc(n * 4), *index = malloc((reads + 64) * 4);
  if (!a || !index) return 1;
  for (size_t i = 0; i < n; ++i) a[i] = (uint32_t)(i * 2654435761u);
  uint64_t s = 88172645463325252ull;
  for (size_t i = 0; i < reads + 64; ++i) {
    s ^= s << 13, s ^= s >> 7, s ^= s << 17;
    index[i] = (uint32_t)((s % (n / 16)) * 16);
  }
  uint32_t v = 1;
  const double t0 = now_seconds();
  for (size_t i = 0; i < reads; ++i) {
    if (mode == 1) __builtin_prefetch(&a[index[i + ahead]]);
    if (mode == 2) {
      volatile uint32_t t = a[index[i + ahead]];
      (void)t;
    }
    uint32_t zero = v;
    __asm__("" : "+r"(zero));  // the read's address depends on the previous read's chain: no overlap by itself
    zero &= 0;
    v = a[index[i] + zero];
    for (int k = 0; k < work; ++k) v = v * 2654435761u + (uint32_t)k;
  }
  const double t = now_seconds() - t0;
  printf("%zu MB, ahead %d, work %d, mode %d: %.1f ns per read (%u)\n", megabytes, ahead, work, mode,
         t / (double)reads * 1e9, v);
  free(a);
  free(index);
  return 0;
}
