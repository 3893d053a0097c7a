// The sphere's exit lobe shape, fitted to the exact walk (issue 12, session 22, frostedexit22).
//
// Reads the dump of FrostedGlassSg.ExitOfTheSphereAroundTheCausticBench (GLIMMER_SPHERE_EXIT_DUMP=<dir>): per
// (roughness, IOR) the single SG of every sg sample (<base>_sg.bin: float32 records pixel, weight, axis xyz,
// sharpness, exit Ng xyz, the pixel's exit axis xyz) and the path's band masses and T (<base>_path.txt). For a shape
// (up to 3 vMFs about the single SG's axis: shares w_j, sharpness factors f_j) it draws each record's directions as
// the renderer does (glimmer/exit_lobe.h: a vMF draw, redrawn up to 16 times while below the exit surface, then
// mirrored) and bins the light by its angle off the pixel's exit axis, as the test does; band L1 against the path.
// Common random numbers across shapes (the same uniforms per record and lobe), so shapes compare without noise of
// their own beyond the dump's.
//
//   g++ -O2 -std=c++20 -o /tmp/fit benchmarks/frosted_sphere_exit_fit.cpp
//   /tmp/fit <base> eval w:f,w:f[,w:f] ...      # band fractions and L1 of the given shapes
//   /tmp/fit <base> fit2                        # grid over 2-lobe shapes (share t, factors f_core, f_tail)
//   /tmp/fit <base> fit3                        # grid over 3-lobe shapes
//   /tmp/fit <base> fit2fine                    # a finer 2-lobe grid (t 0.15-0.3, f_core 1.9-2.7, f_tail 0.28-0.46)
// Session 29 (frostedexit29): <base> may list several cases separated by commas (fit2 / fit3 then rank the shapes by
// the cases' mean L1, and print every case's bands for the best), and --drawn before the mode reads the records
// made under the drawn entry axis (kEntryAxis 1: <base>_drawn_sg.bin) instead of the front SG's (<base>_sg.bin).
#include <algorithm>
#include <array>
#include <cmath>
#include <cstdint>
#include <cstdio>
#include <cstdlib>
#include <cstring>
#include <string>
#include <vector>

namespace {

constexpr int kBands = 8;
constexpr double kEdge[kBands + 1] = {0, 2, 5, 10, 20, 30, 45, 60, 180};
constexpr int kRedraws = 16;

struct V {
  double x, y, z;
};
V operator*(V a, double s) { return {a.x * s, a.y * s, a.z * s}; }
V operator+(V a, V b) { return {a.x + b.x, a.y + b.y, a.z + b.z}; }
V operator-(V a, V b) { return {a.x - b.x, a.y - b.y, a.z - b.z}; }
double dot(V a, V b) { return a.x * b.x + a.y * b.y + a.z * b.z; }
V normalize(V a) { return a * (1.0 / std::sqrt(dot(a, a))); }
V cross(V a, V b) { return {a.y * b.z - a.z * b.y, a.z * b.x - a.x * b.z, a.x * b.y - a.y * b.x}; }

struct Record {
  double weight, kappa;
  V axis, n, chief, s, t;  // s, t: a frame about axis
};

struct Shape {
  int count = 0;
  double w[3] = {}, f[3] = {};
};

uint64_t splitmix(uint64_t &x) {
  uint64_t z = (x += 0x9e3779b97f4a7c15ull);
  z = (z ^ (z >> 30)) * 0xbf58476d1ce4e5b9ull;
  z = (z ^ (z >> 27)) * 0x94d049bb133111ebull;
  return z ^ (z >> 31);
}
double uniform(uint64_t &x) { return double(splitmix(x) >> 11) * 0x1p-53; }

V draw_vmf(const Record &r, double kappa, uint64_t &state) {
  const double u = uniform(state), phi = 2.0 * M_PI * uniform(state);
  // cos theta = 1 + log(u + (1 - u) exp(-2 kappa)) / kappa
  const double c = std::clamp(1.0 + std::log(u + (1.0 - u) * std::exp(-2.0 * kappa)) / kappa, -1.0, 1.0);
  const double sn = std::sqrt(std::max(0.0, 1.0 - c * c));
  return r.axis * c + r.s * (sn * std::cos(phi)) + r.t * (sn * std::sin(phi));
}
V draw_restricted(const Record &r, double kappa, uint64_t &state) {
  V w = draw_vmf(r, kappa, state);
  for (int k = 0; k < kRedraws && dot(w, r.n) <= 0.0; ++k) w = draw_vmf(r, kappa, state);
  const double h = dot(w, r.n);
  return h <= 0.0 ? normalize(w - r.n * (2.0 * h)) : w;
}
int band_of(double deg) {
  int b = 0;
  while (b + 1 < kBands && deg >= kEdge[b + 1]) ++b;
  return b;
}

struct Data {
  std::vector<Record> rec;
  std::array<double, kBands> ref{};
  double ref_total = 0.0;
};

bool load(const std::string &base, const char *records, Data &d) {
  FILE *f = std::fopen((base + "_path.txt").c_str(), "r");
  if (!f) return false;
  for (int b = 0; b < kBands; ++b)
    if (std::fscanf(f, "%lf", &d.ref[size_t(b)]) != 1) return false;
  if (std::fscanf(f, "%lf", &d.ref_total) != 1) return false;
  std::fclose(f);
  f = std::fopen((base + records).c_str(), "rb");
  if (!f) return false;
  float r[12];
  while (std::fread(r, sizeof(float), 12, f) == 12) {
    Record q;
    q.weight = r[1];
    q.axis = normalize(V{r[2], r[3], r[4]});
    q.kappa = r[5];
    q.n = normalize(V{r[6], r[7], r[8]});
    q.chief = normalize(V{r[9], r[10], r[11]});
    const V a = std::fabs(q.axis.x) > 0.9 ? V{0, 1, 0} : V{1, 0, 0};
    q.s = normalize(cross(a, q.axis));
    q.t = cross(q.axis, q.s);
    d.rec.push_back(q);
  }
  std::fclose(f);
  return !d.rec.empty();
}

// Band fractions of a shape: every record draws `draws` directions per lobe (weight w_j / draws each).
std::array<double, kBands> bands(const Data &d, const Shape &sh, int draws = 2) {
  std::array<double, kBands> m{};
  double wsum = 0.0;
  for (int j = 0; j < sh.count; ++j) wsum += sh.w[j];
  double total = 0.0;
  for (size_t i = 0; i < d.rec.size(); ++i) {
    const Record &r = d.rec[i];
    for (int j = 0; j < sh.count; ++j) {
      uint64_t state = (uint64_t(i) << 8) ^ uint64_t(j) * 0x51ull ^ 0x1234567ull;
      const double kappa = std::clamp(r.kappa * sh.f[j], 1e-3, 1e7), w = r.weight * sh.w[j] / wsum / draws;
      for (int k = 0; k < draws; ++k) {
        const V dir = draw_restricted(r, kappa, state);
        const double deg = std::acos(std::clamp(dot(dir, r.chief), -1.0, 1.0)) * 180.0 / M_PI;
        m[size_t(band_of(deg))] += w;
        total += w;
      }
    }
  }
  for (double &x : m) x /= total;
  return m;
}
double l1(const std::array<double, kBands> &m, const std::array<double, kBands> &ref) {
  double s = 0.0;
  for (int b = 0; b < kBands; ++b) s += std::fabs(m[size_t(b)] - ref[size_t(b)]);
  return s;
}
void print(const char *what, const std::array<double, kBands> &m, const Data &d) {
  std::printf("%-28s", what);
  for (int b = 0; b < kBands; ++b) std::printf(" %7.3f", m[size_t(b)] / std::max(d.ref[size_t(b)], 1e-12));
  std::printf(" | L1 %.4f\n", l1(m, d.ref));
}
bool parse(const char *s, Shape &sh) {
  sh = Shape{};
  while (s && *s && sh.count < 3) {
    char *end;
    sh.w[sh.count] = std::strtod(s, &end);
    if (*end != ':') return false;
    sh.f[sh.count] = std::strtod(end + 1, &end);
    ++sh.count;
    s = *end == ',' ? end + 1 : nullptr;
  }
  return sh.count > 0;
}
std::string describe(const Shape &sh) {
  std::string out;
  char buf[64];
  for (int j = 0; j < sh.count; ++j) {
    std::snprintf(buf, sizeof buf, "%s%.3g:%.3g", j ? "," : "", sh.w[j], sh.f[j]);
    out += buf;
  }
  return out;
}

}  // namespace

std::vector<std::string> split_bases(const char *arg) {
  std::vector<std::string> out;
  std::string cur;
  for (const char *p = arg; *p; ++p) {
    if (*p == ',') {
      if (!cur.empty()) out.push_back(cur);
      cur.clear();
    } else {
      cur += *p;
    }
  }
  if (!cur.empty()) out.push_back(cur);
  return out;
}

int main(int argc, char **argv) {
  if (argc < 3) {
    std::fprintf(stderr, "usage: %s <base>[,<base>...] [--drawn] eval|fit2|fit3 [shapes]\n", argv[0]);
    return 2;
  }
  const bool drawn = std::strcmp(argv[2], "--drawn") == 0;
  const int mode_arg = drawn ? 3 : 2;
  if (argc <= mode_arg) return 2;
  std::vector<Data> data;
  for (const std::string &base : split_bases(argv[1])) {
    data.emplace_back();
    if (!load(base, drawn ? "_drawn_sg.bin" : "_sg.bin", data.back())) {
      std::fprintf(stderr, "cannot read %s_{%s,path.txt}\n", base.c_str(), drawn ? "drawn_sg.bin" : "sg.bin");
      return 1;
    }
    const Data &d = data.back();
    std::printf("%s: %zu sg records; path bands", base.c_str(), d.rec.size());
    for (double x : d.ref) std::printf(" %.3e", x);
    std::printf("\n");
  }
  std::printf("%-28s", "band (deg), shape / path:");
  for (int b = 0; b < kBands; ++b) std::printf(" %3g-%-3g", kEdge[b], kEdge[b + 1]);
  std::printf("\n");
  const std::string mode = argv[mode_arg];
  if (mode == "eval") {
    for (int i = mode_arg + 1; i < argc; ++i) {
      Shape sh;
      if (!parse(argv[i], sh)) continue;
      for (const Data &d : data) print(describe(sh).c_str(), bands(d, sh), d);
    }
    return 0;
  }
  struct Best {
    double l1;
    Shape sh;
  };
  std::vector<Best> best;
  auto consider = [&](const Shape &sh) {
    double sum = 0.0;
    for (const Data &d : data) sum += l1(bands(d, sh, 1), d.ref);
    best.push_back({sum / double(data.size()), sh});
  };
  if (mode == "fit2") {
    for (double t : {0.03, 0.05, 0.08, 0.1, 0.13, 0.16, 0.2, 0.25, 0.3})
      for (double fc : {0.8, 1.0, 1.2, 1.5, 1.8, 2.2, 2.7, 3.3})
        for (double ft : {0.08, 0.12, 0.18, 0.25, 0.35, 0.5})
          consider(Shape{2, {1 - t, t}, {fc, ft}});
  } else if (mode == "fit2fine") {  // session 29: about the drawn entry's coarse best (0.75:2.2,0.25:0.35)
    for (double t : {0.15, 0.18, 0.2, 0.22, 0.25, 0.28, 0.3})
      for (double fc : {1.9, 2.05, 2.2, 2.35, 2.5, 2.7})
        for (double ft : {0.28, 0.32, 0.35, 0.38, 0.42, 0.46})
          consider(Shape{2, {1 - t, t}, {fc, ft}});
  } else if (mode == "fit3") {
    for (double t1 : {0.05, 0.1, 0.15, 0.2, 0.3})
      for (double t2 : {0.01, 0.02, 0.04, 0.07})
        for (double fc : {1.0, 1.3, 1.7, 2.2, 3.0})
          for (double f1 : {0.2, 0.3, 0.45, 0.6})
            for (double f2 : {0.03, 0.06, 0.1})
              consider(Shape{3, {1 - t1 - t2, t1, t2}, {fc, f1, f2}});
  }
  std::sort(best.begin(), best.end(), [](const Best &a, const Best &b) { return a.l1 < b.l1; });
  for (size_t i = 0; i < std::min<size_t>(8, best.size()); ++i) {
    std::printf("mean L1 %.4f:\n", best[i].l1);
    for (const Data &d : data) print(describe(best[i].sh).c_str(), bands(d, best[i].sh), d);
  }
  return 0;
}
