// Offline simulation for docs/history/glints_sessions.md "Session 21 (glintdark21)": would a lit-count hierarchy (a
// block of B particle nodes draws K_B ~ Poisson(B lambda) by the same tail inversion; K_B = 0 rejects its B nodes with
// one hash per group; K_B > 0 is split to the nodes by binomial splits) cut the walk's work?
//
// Input: the walk log of benchmarks/glint_dark_walks.patch (one line per direction-cell walk: level, P, density,
// footprint, node list). For every logged walk and R replicas, one realisation of the particle process is drawn
// top-down (per group: a 4 x 4 block's Poisson count, split by binomial splits into 2 x 2 blocks and nodes; the same
// law as independent Poisson counts per node), and the work of each algorithm is counted on that realisation:
//   today  : the node list (rows rasterised), one 4-lane hash per node (pass 2), the (node, group) pairs passing
//            the quick reject (u < lambda), the lit pairs, the paired nodes' origins, the positions drawn on
//            border nodes;
//   Hd     : aligned blocks of 2^d x 2^d nodes (d = 1: 2 x 2, d = 2: 4 x 4): the block list (block rows rasterised),
//            one 4-lane hash per block, passing and lit (block, group) pairs; a lit block descends: a block inside
//            the footprint adds its count in closed form, a block the footprint misses is skipped, a border block
//            splits (binary splits, one per non-empty parent: 3 per 2 x 2 level) and its children descend; border
//            nodes draw their particles' positions (the children overlap tests are counted);
//   Hd-flat: the block is the node (no split; a lit border block draws all its K_B positions), i.e. a coarser
//            particle level;
//   Hd-fa  : blocks aligned to the footprint's first node instead of the grid (not a valid model: the realisation
//            would depend on the footprint; a lower bound of the block count).
// The walk is dark when no lit particle falls in the footprint (the same outcome for every algorithm: one
// realisation). Reported per walk, dark and lit walks apart, and an instruction estimate with the per-operation
// costs given on the command line (defaults: session 20's profile; see docs/history/glints_sessions.md).
//
// build: g++ -O2 -std=c++20 -o /tmp/glint_dark_sim benchmarks/glint_dark_sim.cpp
// usage: glint_dark_sim <walk log> [replicas=8] [filter: all|ggx|beckmann|eval|sample|beckmann-eval] [fitted]
//   fitted: 15 per 4-lane hash and 40 per position instead of 27 and 20 (the costs that reproduce the measured
//   kNodeParticles 512 / 2048 builds; docs/history/glints_sessions.md "Session 21 (glintdark21)")
#include <algorithm>
#include <array>
#include <cmath>
#include <cstdint>
#include <cstdio>
#include <fstream>
#include <functional>
#include <iostream>
#include <map>
#include <random>
#include <set>
#include <sstream>
#include <string>
#include <utility>
#include <vector>

namespace {

struct Walk {
  int material = 0, kind = 0, level = 0;
  double P = 0, gdens = 0;
  double cx = 0, cy = 0, ax = 0, ay = 0, bx = 0, by = 0;
  int count = 0;
  std::vector<std::pair<int64_t, int64_t>> nodes;
};

// Footprint frame: (s, t) of a point; inside when |s|, |t| <= 1/2.
struct Frame {
  double cx, cy, ax, ay, bx, by, inv_det;
  explicit Frame(const Walk &w)
      : cx(w.cx), cy(w.cy), ax(w.ax), ay(w.ay), bx(w.bx), by(w.by), inv_det(1.0 / (w.ax * w.by - w.ay * w.bx)) {}
  bool inside(double x, double y) const {
    const double px = x - cx, py = y - cy;
    const double s = (px * by - py * bx) * inv_det, t = (ax * py - ay * px) * inv_det;
    return std::fabs(s) <= 0.5 && std::fabs(t) <= 0.5;
  }
  // The square [x0, x0 + size] x [y0, y0 + size] inside (its four corners; the footprint is convex).
  bool square_inside(double x0, double y0, double size) const {
    return inside(x0, y0) && inside(x0 + size, y0) && inside(x0, y0 + size) && inside(x0 + size, y0 + size);
  }
};

int64_t floor_div_pow2(int64_t v, int d) { return v >> d; }  // arithmetic shift: floor for negatives (GCC)

struct Ops {  // per-walk work
  double raster = 0;  // 1 when the list is rasterised (the footprint's box spans more than 2 x 2 nodes / blocks)
  double rows = 0, hash4 = 0, pass = 0, lit = 0, origins = 0, splits = 0, child_tests = 0, positions = 0,
         closed = 0;
  void add(const Ops &o, double w = 1.0) {
    raster += w * o.raster, rows += w * o.rows, hash4 += w * o.hash4, pass += w * o.pass, lit += w * o.lit, origins += w * o.origins;
    splits += w * o.splits, child_tests += w * o.child_tests, positions += w * o.positions, closed += w * o.closed;
  }
};

// Per-operation instruction costs (estimates; varied in the sensitivity table). Calibrated on main 8e151ad's GI
// render (callgrind, 160 x 100, 4 spp): footprint_nodes 61.6 M in 69 389 calls (self 181 per call: the rows' start,
// the box path, the memo), nodes_at_level_rows 1082 per call in 43 275 calls (4.89 rows per rasterised list in the
// walk log: ~150 + 190 per row), count_four_groups_in_passes 992 per call in 68 213 calls (~350 fixed + the
// per-node, per-pair, per-origin and per-position terms below: 27, 40, 25, 20 give the rest at the log's means).
struct Costs {
  double fixed = 181 + 350;  // footprint_nodes' own and the passes' fixed part (the same in every algorithm)
  double memo = 0.624;       // the share of walks whose list is rasterised (not in the node-list memo): 43 275 / 69 389
  double list_call = 150;    // rasteriser per call
  double row = 190;          // rasteriser per row
  double hash4 = 27;         // pass 2 per node (AVX2, session 20: ~27 per node)
  double pass = 40;          // pass 3 per passing pair (bounds, add_lit)
  double origin = 25;        // pass 1 per paired node / block test (origin and inside test)
  double split = 30;         // one binary split (a hash lane and a small binomial inversion)
  double child_test = 15;    // a child's overlap test with the footprint
  double position = 20;      // one lit particle's position and membership (pass 4)
  double instr(const Ops &o) const {
    return fixed + memo * (list_call * o.raster + row * o.rows) + hash4 * o.hash4 + pass * o.pass + origin * o.origins +
           split * o.splits + child_test * o.child_tests + position * o.positions;
  }
};

struct Tally {
  double walks = 0;
  Ops ops;
};

// Poisson(mean) by tail inversion of a uniform (the walk's LitCountModel law).
int64_t poisson_inv(double u, double mean) {
  double pmf = std::exp(-mean), tail = 1.0 - pmf;
  int64_t k = 0;
  while (u < tail && pmf > 0.0) {
    ++k;
    pmf *= mean / static_cast<double>(k);
    tail -= pmf;
  }
  return k;
}
// Whether the quick reject passes a pair with count K at mean `mean` (u < min(mean, 1) where u is uniform on K's
// inversion interval): always for K > 0; for K = 0 with probability (min(mean,1) - (1 - e^-mean)) / e^-mean.
bool quick_pass(int64_t K, double mean, std::mt19937_64 &rng) {
  if (K > 0) return true;
  const double p0 = std::exp(-mean);
  const double q = (std::min(mean, 1.0) - (1.0 - p0)) / p0;
  return std::uniform_real_distribution<double>(0.0, 1.0)(rng) < q;
}

struct Sim {
  static constexpr int kDepth = 2;  // realisation drawn from 4 x 4 blocks down
  const Walk &w;
  Frame fr;
  double size, lambda;
  std::set<std::pair<int64_t, int64_t>> node_set;
  // Realisation: per group, per node, the count and the positions of its particles (node-relative units).
  struct NodeReal {
    int64_t K = 0;
    std::vector<std::pair<double, double>> pos;
  };
  std::map<std::pair<int64_t, int64_t>, std::array<NodeReal, 4>> real;  // only nodes with a particle
  std::mt19937_64 &rng;
  // Blocks (depth, i, j) whose origin / children's overlap were computed in this query (shared by the groups).
  std::set<std::array<int64_t, 3>> visited, child_tested;

  Sim(const Walk &wk, std::mt19937_64 &r) : w(wk), fr(wk), rng(r) {
    size = std::ldexp(1.0, -w.level);
    lambda = w.gdens * size * size * std::min(w.P, 1.0);
    for (auto &n : w.nodes) node_set.insert(n);
  }
  double uni() { return std::uniform_real_distribution<double>(0.0, 1.0)(rng); }
  int64_t binom_half(int64_t K) {
    int64_t x = 0;
    for (int64_t k = 0; k < K; ++k) x += uni() < 0.5 ? 1 : 0;
    return x;
  }
  // Split a count over the 2^d x 2^d nodes of block (bi, bj) at depth d.
  void split_down(int64_t bi, int64_t bj, int d, int64_t K, int g) {
    if (K == 0) return;
    if (d == 0) {
      NodeReal &n = real[{bi, bj}][static_cast<size_t>(g)];
      n.K = K;
      for (int64_t k = 0; k < K; ++k) n.pos.emplace_back(uni(), uni());
      return;
    }
    const int64_t left = binom_half(K), right = K - left;
    const int64_t ll = binom_half(left), rl = binom_half(right);
    split_down(2 * bi, 2 * bj, d - 1, ll, g);
    split_down(2 * bi, 2 * bj + 1, d - 1, left - ll, g);
    split_down(2 * bi + 1, 2 * bj, d - 1, rl, g);
    split_down(2 * bi + 1, 2 * bj + 1, d - 1, right - rl, g);
  }
  void draw() {
    real.clear();
    std::set<std::pair<int64_t, int64_t>> tops;
    for (auto &n : w.nodes) tops.insert({floor_div_pow2(n.first, kDepth), floor_div_pow2(n.second, kDepth)});
    const double mean = lambda * std::ldexp(1.0, 2 * kDepth);
    for (auto &t : tops)
      for (int g = 0; g < 4; ++g) split_down(t.first, t.second, kDepth, poisson_inv(uni(), mean), g);
  }
  int64_t count_in_block(int64_t bi, int64_t bj, int d, int g) const {  // realisation's count in a block
    int64_t K = 0;
    const int64_t n = int64_t{1} << d;
    for (int64_t a = 0; a < n; ++a)
      for (int64_t b = 0; b < n; ++b) {
        auto it = real.find({bi * n + a, bj * n + b});
        if (it != real.end()) K += it->second[static_cast<size_t>(g)].K;
      }
    return K;
  }
  bool node_inside(int64_t i, int64_t j) const {
    return fr.square_inside(static_cast<double>(i) * size, static_cast<double>(j) * size, size);
  }
  int64_t node_lit_in_footprint(int64_t i, int64_t j, int g) const {
    auto it = real.find({i, j});
    if (it == real.end()) return 0;
    const NodeReal &n = it->second[static_cast<size_t>(g)];
    if (n.K == 0) return 0;
    if (node_inside(i, j)) return n.K;
    int64_t c = 0;
    for (auto &p : n.pos)
      c += fr.inside((static_cast<double>(i) + p.first) * size, (static_cast<double>(j) + p.second) * size) ? 1 : 0;
    return c;
  }
  int64_t outcome() const {
    int64_t c = 0;
    for (auto &n : w.nodes)
      for (int g = 0; g < 4; ++g) c += node_lit_in_footprint(n.first, n.second, g);
    return c;
  }
  // Today's walk.
  Ops today() {
    Ops o;
    std::set<int64_t> rows, cols;
    for (auto &n : w.nodes) rows.insert(n.second), cols.insert(n.first);
    o.raster = (rows.size() > 2 || cols.size() > 2) ? 1.0 : 0.0;
    o.rows = o.raster * static_cast<double>(rows.size());
    o.hash4 = static_cast<double>(w.nodes.size());
    for (auto &n : w.nodes) {
      bool paired = false;
      auto it = real.find(n);
      for (int g = 0; g < 4; ++g) {
        const int64_t K = it == real.end() ? 0 : it->second[static_cast<size_t>(g)].K;
        if (!quick_pass(K, lambda, rng)) continue;
        paired = true;
        o.pass += 1;
        if (K == 0) continue;
        o.lit += 1;
        if (node_inside(n.first, n.second)) o.closed += 1;
        else o.positions += static_cast<double>(K);
      }
      o.origins += paired ? 1 : 0;
    }
    return o;
  }
  // Whether any node of block (bi, bj) at depth d (grid offset oi, oj) is in the footprint's node list.
  bool block_overlaps(int64_t bi, int64_t bj, int d, int64_t oi, int64_t oj) const {
    const int64_t n = int64_t{1} << d;
    for (int64_t a = 0; a < n; ++a)
      for (int64_t b = 0; b < n; ++b)
        if (node_set.count({bi * n + a + oi, bj * n + b + oj})) return true;
    return false;
  }
  // Count a block's particles in a footprint-relative grid (offset oi, oj): the count of its nodes.
  int64_t count_in_block_off(int64_t bi, int64_t bj, int d, int g, int64_t oi, int64_t oj) const {
    int64_t K = 0;
    const int64_t n = int64_t{1} << d;
    for (int64_t a = 0; a < n; ++a)
      for (int64_t b = 0; b < n; ++b) {
        auto it = real.find({bi * n + a + oi, bj * n + b + oj});
        if (it != real.end()) K += it->second[static_cast<size_t>(g)].K;
      }
    return K;
  }
  // Descend a lit block (count K > 0) at depth e.
  void descend(int64_t bi, int64_t bj, int e, int64_t K, int g, int64_t oi, int64_t oj, bool flat, Ops &o) {
    const int64_t n = int64_t{1} << e;
    const double bsize = size * static_cast<double>(n);
    if (visited.insert({e, bi, bj}).second) o.origins += 1;  // the block's origin and inside test, once per block
    if (fr.square_inside(static_cast<double>(bi * n + oi) * size, static_cast<double>(bj * n + oj) * size, bsize)) {
      o.closed += 1;
      return;
    }
    if (e == 0 || flat) {
      o.positions += static_cast<double>(K);
      return;
    }
    // Binary splits: x then y, one per non-empty parent.
    const int64_t half = n / 2;
    int64_t kc[4];
    int c = 0;
    for (int64_t a = 0; a < 2; ++a)
      for (int64_t b = 0; b < 2; ++b) kc[c++] = count_in_block_off(2 * bi + a, 2 * bj + b, e - 1, g, oi, oj);
    (void)half;
    const int64_t left = kc[0] + kc[1], right = kc[2] + kc[3];
    o.splits += (K > 0 ? 1 : 0) + (left > 0 ? 1 : 0) + (right > 0 ? 1 : 0);
    c = 0;
    for (int64_t a = 0; a < 2; ++a)
      for (int64_t b = 0; b < 2; ++b, ++c) {
        if (kc[c] == 0) continue;
        if (child_tested.insert({e - 1, 2 * bi + a, 2 * bj + b}).second) o.child_tests += 1;
        if (!block_overlaps(2 * bi + a, 2 * bj + b, e - 1, oi, oj)) continue;
        descend(2 * bi + a, 2 * bj + b, e - 1, kc[c], g, oi, oj, false, o);
      }
  }
  // The hierarchy with blocks of 2^d x 2^d nodes; fa: grid offset to the footprint's first node.
  Ops hierarchy(int d, bool flat, bool fa) {
    Ops o;
    int64_t oi = 0, oj = 0;
    if (fa) {
      oi = w.nodes[0].first, oj = w.nodes[0].second;
      for (auto &n : w.nodes) oi = std::min(oi, n.first), oj = std::min(oj, n.second);
    }
    visited.clear(), child_tested.clear();
    std::set<std::pair<int64_t, int64_t>> blocks;
    std::set<int64_t> rows, cols;
    for (auto &n : w.nodes) {
      blocks.insert({floor_div_pow2(n.first - oi, d), floor_div_pow2(n.second - oj, d)});
      rows.insert(floor_div_pow2(n.second - oj, d));
      cols.insert(floor_div_pow2(n.first - oi, d));
    }
    o.raster = (rows.size() > 2 || cols.size() > 2) ? 1.0 : 0.0;
    o.rows = o.raster * static_cast<double>(rows.size());
    o.hash4 = static_cast<double>(blocks.size());
    const double mean = lambda * std::ldexp(1.0, 2 * d);
    for (auto &b : blocks)
      for (int g = 0; g < 4; ++g) {
        const int64_t K = count_in_block_off(b.first, b.second, d, g, oi, oj);
        if (!quick_pass(K, mean, rng)) continue;
        o.pass += 1;
        if (K == 0) continue;
        o.lit += 1;
        descend(b.first, b.second, d, K, g, oi, oj, flat, o);
      }
    // descend counted one origin per visited block; the top blocks' origins are per lit pair here (an upper
    // bound: today's counts one per paired node).
    return o;
  }
};

bool parse(const std::string &line, Walk &w) {
  std::istringstream in(line);
  std::string tag;
  in >> tag;
  if (tag != "W") return false;
  int n, steps, complete;
  in >> w.material >> w.kind >> w.level >> w.P >> w.gdens >> w.cx >> w.cy >> w.ax >> w.ay >> w.bx >> w.by >> n >>
      w.count >> steps >> complete;
  if (n <= 0) return false;
  w.nodes.resize(static_cast<size_t>(n));
  for (auto &p : w.nodes) in >> p.first >> p.second;
  return static_cast<bool>(in);
}

}  // namespace

int main(int argc, char **argv) {
  if (argc < 2) {
    std::fprintf(stderr, "usage: %s <walk log> [replicas] [filter]\n", argv[0]);
    return 1;
  }
  const int replicas = argc > 2 ? std::atoi(argv[2]) : 8;
  const std::string filter = argc > 3 ? argv[3] : "all";
  const bool fitted = argc > 4 && std::string(argv[4]) == "fitted";
  std::ifstream file(argv[1]);
  std::string line;
  std::mt19937_64 rng(12345);
  const char *names[] = {"today", "H1 2x2", "H2 4x4", "H1-flat", "H2-flat", "H1-fa", "H2-fa"};
  constexpr int kAlgos = 7;
  Tally tally[2][kAlgos];  // [lit][algo]
  double logged_walks = 0, logged_dark = 0, nodes_total = 0, lambda_sum = 0;
  Costs costs;
  if (fitted) costs.hash4 = 15, costs.position = 40;  // fitted to the measured coarser levels (see Costs)
  while (std::getline(file, line)) {
    Walk w;
    if (!parse(line, w)) continue;
    if (filter == "ggx" && w.material != 0) continue;
    if (filter == "beckmann" && w.material != 1) continue;
    if (filter == "eval" && w.kind != 0) continue;
    if (filter == "sample" && w.kind != 1) continue;
    if (filter == "beckmann-eval" && (w.material != 1 || w.kind != 0)) continue;
    logged_walks += 1;
    logged_dark += w.count == 0 ? 1 : 0;
    nodes_total += static_cast<double>(w.nodes.size());
    Sim sim(w, rng);
    lambda_sum += sim.lambda;
    for (int r = 0; r < replicas; ++r) {
      sim.draw();
      const int lit = sim.outcome() > 0 ? 1 : 0;
      const Ops ops[kAlgos] = {sim.today(),          sim.hierarchy(1, false, false), sim.hierarchy(2, false, false),
                               sim.hierarchy(1, true, false), sim.hierarchy(2, true, false),
                               sim.hierarchy(1, false, true), sim.hierarchy(2, false, true)};
      for (int a = 0; a < kAlgos; ++a) {
        tally[lit][a].walks += 1.0 / replicas;
        tally[lit][a].ops.add(ops[a], 1.0 / replicas);
      }
    }
  }
  std::printf("filter %s: %.0f logged walks, logged dark %.1f %%, mean nodes %.2f, mean lambda per (node, group) %.4g\n",
              filter.c_str(), logged_walks, 100.0 * logged_dark / logged_walks, nodes_total / logged_walks,
              lambda_sum / logged_walks);
  const auto per_walk = [&](int lit, int a) {  // lit: 0 dark, 1 lit, 2 all
    Ops m;
    const double nw = lit == 2 ? logged_walks : tally[lit][0].walks;
    for (int l = 0; l < 2; ++l)
      if (lit == 2 || lit == l) m.add(tally[l][a].ops, 1.0 / nw);
    return m;
  };
  for (int lit = 0; lit < 3; ++lit) {
    const double nw = lit == 2 ? logged_walks : tally[lit][0].walks;
    std::printf("\n%s walks (simulated): %.0f (%.1f %%); per walk:\n", lit == 0 ? "DARK" : lit == 1 ? "LIT" : "ALL", nw,
                100.0 * nw / logged_walks);
    std::printf("%-9s %6s %6s %6s %7s %7s %7s %7s %7s %7s %7s %8s %8s %9s\n", "algo", "raster", "rows", "hash4", "pass",
                "lit", "origins", "splits", "ctests", "pos", "closed", "instr", "vs today", "total M");
    const double base = costs.instr(per_walk(lit, 0));
    for (int a = 0; a < kAlgos; ++a) {
      const Ops m = per_walk(lit, a);
      const double ins = costs.instr(m);
      std::printf("%-9s %6.3f %6.2f %6.2f %7.3f %7.3f %7.3f %7.3f %7.3f %7.3f %7.3f %8.1f %+8.1f %+9.2f\n", names[a],
                  m.raster, m.rows, m.hash4, m.pass, m.lit, m.origins, m.splits, m.child_tests, m.positions, m.closed,
                  ins, ins - base, (ins - base) * nw / 1e6);
    }
  }
  // Sensitivity of the all-walk difference to the assumed per-operation costs.
  std::printf("\nSensitivity (all walks, instructions per walk vs today):\n%-30s", "costs");
  for (int a = 1; a < kAlgos; ++a) std::printf(" %9s", names[a]);
  std::printf("\n");
  const std::pair<const char *, std::function<void(Costs &)>> variants[] = {
      {"defaults", [](Costs &) {}},
      {"split 60, ctest 30", [](Costs &c) { c.split = 60, c.child_test = 30; }},
      {"split 15, ctest 8", [](Costs &c) { c.split = 15, c.child_test = 8; }},
      {"position 40", [](Costs &c) { c.position = 40; }},
      {"pass 80", [](Costs &c) { c.pass = 80; }},
      {"row 120, list_call 500", [](Costs &c) { c.row = 120, c.list_call = 500; }},
      {"hash4 15", [](Costs &c) { c.hash4 = 15; }},
      {"origin 50", [](Costs &c) { c.origin = 50; }},
      // Fits the measured coarser particle level (kNodeParticles 512, passes for every footprint; docs/glints.md):
      {"calibrated: hash4 15, pos 40", [](Costs &c) { c.hash4 = 15, c.position = 40; }},
  };
  for (auto &[label, change] : variants) {
    Costs c = costs;
    change(c);
    std::printf("%-30s", label);
    const double base = c.instr(per_walk(2, 0));
    for (int a = 1; a < kAlgos; ++a) std::printf(" %+9.1f", c.instr(per_walk(2, a)) - base);
    std::printf("\n");
  }
  return 0;
}
