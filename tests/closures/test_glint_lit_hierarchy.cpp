// The binomial split of a block's lit count to its nodes (plugin/tables/glint_lit_hierarchy.h; issue 10, session
// 21): nested in K and in P, and exact (the children independent Poisson with the right means), each against brute
// force, each with a negative control that the same check rejects.
#include <gtest/gtest.h>

#include <algorithm>
#include <array>
#include <cmath>
#include <cstdint>
#include <cstdio>
#include <functional>
#include <map>
#include <vector>

#include "glimmer/rng.h"
#include "tables/glint_lit_hierarchy.h"
#include "tables/glint_particles.h"

namespace glimmer {
namespace {

namespace pg = plugin::glint;

// K_B of a block with hash h at block mean `mean` (the walk's inversion: u = (h + 1/2) 2^-32).
int64_t block_count(uint32_t h, double mean) {
  const double u = (static_cast<double>(h) + 0.5) * (1.0 / 4294967296.0);
  const pg::LitCountModel m(mean);
  return u < m.p_any ? m.lit(u) : 0;
}

double binomial_pmf(int64_t K, double p, int64_t x) {
  return std::exp(std::lgamma(K + 1.0) - std::lgamma(x + 1.0) - std::lgamma(K - x + 1.0) + x * std::log(p) +
                  (K - x) * std::log1p(-p));
}
double poisson_pmf(double mean, int64_t k) { return std::exp(k * std::log(mean) - mean - std::lgamma(k + 1.0)); }

// Pearson chi2 of observed against expected counts, cells with expected < 5 pooled into one; df = cells - 1.
struct Chi2 {
  double value = 0.0;
  int df = 0;
  // p ~ 1e-7 for a chi2 of df degrees of freedom (Wilson-Hilferty: z = 5.2).
  double limit() const {
    const double k = df, z = 5.2, a = 2.0 / (9.0 * k);
    return k * std::pow(1.0 - a + z * std::sqrt(a), 3.0);
  }
  bool passes() const { return value <= limit(); }
};
Chi2 chi2(const std::vector<double> &observed, const std::vector<double> &expected) {
  Chi2 r;
  double po = 0.0, pe = 0.0;
  int cells = 0;
  for (size_t c = 0; c < observed.size(); ++c) {
    if (expected[c] < 5.0) {
      po += observed[c], pe += expected[c];
      continue;
    }
    r.value += (observed[c] - expected[c]) * (observed[c] - expected[c]) / expected[c];
    ++cells;
  }
  if (pe >= 5.0) r.value += (po - pe) * (po - pe) / pe, ++cells;
  else if (po > 0.0 && pe > 0.0) r.value += (po - pe) * (po - pe) / std::max(pe, 1e-300);  // a pooled tail < 5
  r.df = std::max(cells - 1, 1);
  return r;
}
// Two-sample chi2 (equal sample sizes) of two histograms, cells with a total < 10 pooled.
Chi2 chi2_two_sample(const std::vector<double> &a, const std::vector<double> &b) {
  Chi2 r;
  double pa = 0.0, pb = 0.0;
  int cells = 0;
  for (size_t c = 0; c < a.size(); ++c) {
    if (a[c] + b[c] < 10.0) {
      pa += a[c], pb += b[c];
      continue;
    }
    r.value += (a[c] - b[c]) * (a[c] - b[c]) / (a[c] + b[c]);
    ++cells;
  }
  if (pa + pb > 0.0) r.value += (pa - pb) * (pa - pb) / (pa + pb), ++cells;
  r.df = std::max(cells - 1, 1);
  return r;
}

// binomial_inverse is nested in K (X(K, u) <= X(K + 1, u) <= X(K, u) + 1 for every u) on a fine u grid and the
// 32-bit lattice around every CDF value, and its histogram over the u grid is the Binomial(K, p) pmf within the
// grid's resolution (brute force: the pmf from lgamma). Negative control: a split whose uniform depends on K
// (u re-hashed per K: the right law, as a fresh draw has) is not nested.
TEST(GlintLitHierarchy, BinomialInverseIsNestedInKAndExact) {
  const int grid = 20000, pmf_grid = 200000;
  int64_t steps_up = 0, steps_same = 0, control_violations = 0;
  for (double p : {0.5, 0.3}) {
    for (int64_t K = 0; K <= 200; ++K) {
      std::vector<double> us;
      for (int g = 0; g < grid; ++g) us.push_back((g + 0.5) / grid);
      double cdf = 0.0;
      for (int64_t x = 0; x <= K && K <= 40; ++x) {  // the lattice around each CDF value (small K: all of them)
        cdf += binomial_pmf(K, p, x);
        const double h = std::floor(cdf * 4294967296.0);
        for (int d = -50; d <= 50; ++d) us.push_back((h + d + 0.5) / 4294967296.0);
      }
      std::vector<double> hist(static_cast<size_t>(K) + 1, 0.0);  // the pmf check's histogram
      for (size_t n = 0; n < us.size(); ++n) {
        const double u = us[n];
        if (!(u > 0.0 && u < 1.0)) continue;
        const int64_t x0 = pg::binomial_inverse(K, p, u), x1 = pg::binomial_inverse(K + 1, p, u);
        ASSERT_GE(x1, x0) << "K " << K << " u " << u;
        ASSERT_LE(x1, x0 + 1) << "K " << K << " u " << u;
        steps_up += x1 > x0, steps_same += x1 == x0;
        // Control: K + 1's uniform re-hashed (a fresh uniform per K).
        const double v = (static_cast<double>(pg::mix_u32(static_cast<uint32_t>(u * 4294967296.0) ^
                                                          static_cast<uint32_t>(K + 1))) + 0.5) / 4294967296.0;
        const int64_t xc = pg::binomial_inverse(K + 1, p, v);
        control_violations += (xc < x0) || (xc > x0 + 1);
      }
      if (K == 1 || K == 2 || K == 7 || K == 40 || K == 200) {  // the pmf on a finer grid
        std::fill(hist.begin(), hist.end(), 0.0);
        for (int g = 0; g < pmf_grid; ++g) hist[static_cast<size_t>(pg::binomial_inverse(K, p, (g + 0.5) / pmf_grid))] += 1.0;
        double worst = 0.0;
        for (int64_t x = 0; x <= K; ++x)
          worst = std::max(worst, std::fabs(hist[static_cast<size_t>(x)] / pmf_grid - binomial_pmf(K, p, x)));
        EXPECT_LE(worst, 2.0 / pmf_grid) << "K " << K << " p " << p;
        // Control: the pmf of K + 1 is not K's (the check resolves one particle more).
        if (K >= 7) {
          double control = 0.0;
          for (int64_t x = 0; x <= K; ++x)
            control = std::max(control, std::fabs(hist[static_cast<size_t>(x)] / pmf_grid - binomial_pmf(K + 1, p, x)));
          EXPECT_GT(control, 10.0 / pmf_grid) << "K " << K << " p " << p;
        }
      }
    }
  }
  std::printf("[split] nested in K: %lld steps up, %lld same; control (fresh uniform per K): %lld violations\n",
              static_cast<long long>(steps_up), static_cast<long long>(steps_same),
              static_cast<long long>(control_violations));
  EXPECT_GT(steps_up, 1000000);
  EXPECT_GT(steps_same, 1000000);
  EXPECT_GT(control_violations, 100000);
}

// The 2 x 2 split of a block's count is nested in P: for a fixed block hash and lambda1 < lambda2 every child's
// count at lambda2 is >= its count at lambda1 (the block's K_B nested in P, the split nested in K_B, its uniforms
// independent of P). Negative control: split uniforms that depend on P (the hash xor lambda's bits) are not.
TEST(GlintLitHierarchy, SplitIsNestedInP) {
  Pcg32 rng(23);
  int64_t increases = 0, control_violations = 0;
  for (int t = 0; t < 200000; ++t) {
    const uint32_t h = rng.next_u32();
    const double l1 = 10.0 * rng.next_double() * rng.next_double(), l2 = l1 + 2.0 * rng.next_double();
    const int64_t k1 = block_count(h, 4.0 * l1), k2 = block_count(h, 4.0 * l2);
    ASSERT_LE(k1, k2);
    const auto c1 = pg::split_block_2x2(h, k1), c2 = pg::split_block_2x2(h, k2);
    for (int c = 0; c < 4; ++c) {
      ASSERT_LE(c1[static_cast<size_t>(c)], c2[static_cast<size_t>(c)]) << "h " << h << " lambda " << l1 << " -> " << l2;
      increases += c2[static_cast<size_t>(c)] > c1[static_cast<size_t>(c)];
    }
    ASSERT_EQ(c1[0] + c1[1] + c1[2] + c1[3], k1);
    const auto bits = [](double l) { return static_cast<uint32_t>(std::llround(l * 1e6)); };
    const auto d1 = pg::split_block_2x2(h ^ bits(l1), k1), d2 = pg::split_block_2x2(h ^ bits(l2), k2);
    for (int c = 0; c < 4; ++c) control_violations += d2[static_cast<size_t>(c)] < d1[static_cast<size_t>(c)];
  }
  std::printf("[split] nested in P: %lld child increases; control (uniforms depend on P): %lld violations\n",
              static_cast<long long>(increases), static_cast<long long>(control_violations));
  EXPECT_GT(increases, 100000);
  EXPECT_GT(control_violations, 10000);
}

// A block's count K_B ~ Poisson(4 lambda) from its hash, split by split_block_2x2: the four children are
// independent Poisson(lambda), as four independent nodes (today's walk) are. Over 400 000 blocks of random hashes
// per lambda: each child's histogram against the Poisson pmf, each pair of children's joint histogram against the
// product of the pmfs (independence), and the histogram of the whole 4-tuple (each count capped at 3: 256 cells)
// against a brute-force run of four independent Poisson(lambda) nodes (two-sample chi2); all at p ~ 1e-7. Negative controls: p = 0.53 in the column
// split (wrong marginals), and the two row splits sharing one uniform (right marginals, dependent children).
TEST(GlintLitHierarchy, SplitChildrenAreIndependentPoisson) {
  const int blocks = 400000;
  using Split = std::function<std::array<int64_t, 4>(uint32_t, int64_t)>;
  const Split exact = [](uint32_t h, int64_t K) { return pg::split_block_2x2(h, K); };
  const Split biased = [](uint32_t h, int64_t K) {
    const int64_t col0 = pg::binomial_inverse(K, 0.53, pg::split_uniform(h, 0)), col1 = K - col0;
    const int64_t c00 = pg::binomial_inverse(col0, 0.5, pg::split_uniform(h, 1));
    const int64_t c10 = pg::binomial_inverse(col1, 0.5, pg::split_uniform(h, 2));
    return std::array<int64_t, 4>{c00, col0 - c00, c10, col1 - c10};
  };
  const Split shared = [](uint32_t h, int64_t K) {
    const int64_t col0 = pg::binomial_inverse(K, 0.5, pg::split_uniform(h, 0)), col1 = K - col0;
    const int64_t c00 = pg::binomial_inverse(col0, 0.5, pg::split_uniform(h, 1));
    const int64_t c10 = pg::binomial_inverse(col1, 0.5, pg::split_uniform(h, 1));  // the same uniform
    return std::array<int64_t, 4>{c00, col0 - c00, c10, col1 - c10};
  };
  struct Result {
    double worst_marginal = 0.0, worst_pair = 0.0, tuple = 0.0;  // chi2 / limit
  };
  const auto run = [&](const Split &split, double lambda, uint64_t seed) {
    Result r;
    const int m = std::max(4, static_cast<int>(std::ceil(lambda + 6.0 * std::sqrt(lambda) + 3.0)));  // bins 0..m
    const auto bin = [&](int64_t k) { return static_cast<size_t>(std::min<int64_t>(k, m)); };
    std::vector<double> pmf(static_cast<size_t>(m) + 1);
    double below = 0.0;
    for (int k = 0; k < m; ++k) pmf[static_cast<size_t>(k)] = poisson_pmf(lambda, k), below += pmf[static_cast<size_t>(k)];
    pmf[static_cast<size_t>(m)] = std::max(0.0, 1.0 - below);
    std::array<std::vector<double>, 4> marg;
    for (auto &v : marg) v.assign(pmf.size(), 0.0);
    std::map<std::pair<int, int>, std::vector<double>> pairs;
    std::map<std::array<int64_t, 4>, std::array<double, 2>> tuples;
    Pcg32 rng(seed), brute(seed + 1000);
    const double block_mean = 4.0 * lambda;
    for (int b = 0; b < blocks; ++b) {
      const uint32_t h = rng.next_u32();
      const auto c = split(h, block_count(h, block_mean));
      std::array<int64_t, 4> binned{};
      for (int a = 0; a < 4; ++a) {
        binned[static_cast<size_t>(a)] = std::min<int64_t>(c[static_cast<size_t>(a)], 3);
        marg[static_cast<size_t>(a)][bin(c[static_cast<size_t>(a)])] += 1.0;
      }
      for (int a = 0; a < 4; ++a)
        for (int d = a + 1; d < 4; ++d) {
          auto &v = pairs[{a, d}];
          if (v.empty()) v.assign(pmf.size() * pmf.size(), 0.0);
          v[bin(c[static_cast<size_t>(a)]) * pmf.size() + bin(c[static_cast<size_t>(d)])] += 1.0;
        }
      tuples[binned][0] += 1.0;
      // Brute force: four independent nodes, each Poisson(lambda) by the same inversion of its own uniform.
      std::array<int64_t, 4> nodes{};
      for (int a = 0; a < 4; ++a) nodes[static_cast<size_t>(a)] = std::min<int64_t>(block_count(brute.next_u32(), lambda), 3);
      tuples[nodes][1] += 1.0;
    }
    std::vector<double> expected(pmf.size());
    for (size_t k = 0; k < pmf.size(); ++k) expected[k] = blocks * pmf[k];
    for (auto &v : marg) {
      const Chi2 x = chi2(v, expected);
      r.worst_marginal = std::max(r.worst_marginal, x.value / x.limit());
    }
    std::vector<double> product(pmf.size() * pmf.size());
    for (size_t a = 0; a < pmf.size(); ++a)
      for (size_t d = 0; d < pmf.size(); ++d) product[a * pmf.size() + d] = blocks * pmf[a] * pmf[d];
    for (auto &kv : pairs) {
      const Chi2 x = chi2(kv.second, product);
      r.worst_pair = std::max(r.worst_pair, x.value / x.limit());
    }
    std::vector<double> ta, tb;
    for (auto &kv : tuples) ta.push_back(kv.second[0]), tb.push_back(kv.second[1]);
    const Chi2 x = chi2_two_sample(ta, tb);
    r.tuple = x.value / x.limit();
    return r;
  };
  bool biased_caught = false, shared_caught = false;
  uint64_t seed = 31;
  for (double lambda : {0.02, 0.3, 1.5, 6.0}) {
    const Result e = run(exact, lambda, seed), b = run(biased, lambda, seed), s = run(shared, lambda, seed);
    std::printf("[split] lambda %-4g chi2/limit: exact marginal %.3f pair %.3f tuple %.3f | p = 0.53: %.2f %.2f %.2f |"
                " shared uniform: %.2f %.2f %.2f\n",
                lambda, e.worst_marginal, e.worst_pair, e.tuple, b.worst_marginal, b.worst_pair, b.tuple,
                s.worst_marginal, s.worst_pair, s.tuple);
    EXPECT_LE(e.worst_marginal, 1.0) << "lambda " << lambda;
    EXPECT_LE(e.worst_pair, 1.0) << "lambda " << lambda;
    EXPECT_LE(e.tuple, 1.0) << "lambda " << lambda;
    if (lambda >= 0.3) {  // the controls must fail where the sample resolves them
      EXPECT_GT(b.worst_marginal, 1.0) << "lambda " << lambda;
      EXPECT_GT(s.worst_pair, 1.0) << "lambda " << lambda;
      EXPECT_LE(s.worst_marginal, 1.0) << "lambda " << lambda;  // the shared uniform keeps the marginals
    }
    biased_caught |= b.worst_marginal > 1.0 && b.tuple > 1.0;
    shared_caught |= s.worst_pair > 1.0 && s.tuple > 1.0;
    seed += 7;
  }
  EXPECT_TRUE(biased_caught);
  EXPECT_TRUE(shared_caught);
}

}  // namespace
}  // namespace glimmer
