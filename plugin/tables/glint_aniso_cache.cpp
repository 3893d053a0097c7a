// Disk cache and process-wide provider of the anisotropic glint energy table
// (tables/glint_aniso.h). The scheme of the isotropic tables
// (glint_tables.cpp): a file per parameter set named by a 64-bit key of every
// parameter the values depend on, 0600 in a private 0700 folder, written
// atomically (glimmer/atomic_file.h), authenticated by HMAC-SHA256 keyed by
// the folder's secret (glimmer/cache_key.h). After the MAC, the values are
// validated: finite and positive, the unblurred level's scales <= 1 (the
// build only scales level 0 down, to the smooth albedo), and `spot_checks`
// nodes picked at random per load recomputed and compared (a table edited by
// someone who knows the key is caught when the edit covers a recomputed node:
// always for an edit of a whole level or of a constant factor).
#include <chrono>
#include <cstdio>
#include <cstring>
#include <filesystem>
#include <fstream>
#include <map>
#include <mutex>
#include <random>

#include "glimmer/cache_blob.h"
#include "tables/glint_aniso.h"

namespace glimmer::plugin::glint {
namespace {

constexpr uint32_t kAnisoFormatVersion = 1;
constexpr char kAnisoMagic[8] = {'G', 'L', 'M', 'G', 'L', 'N', 'T', 'A'};
// Relative tolerance of a recomputed node against the file (the build is
// deterministic; this only absorbs another compiler's rounding).
constexpr double kSpotCheckTolerance = 1e-5;

// The table's shape and construction constants, in the key and the header.
std::array<int32_t, 4> table_dims() {
  return {AnisoEnergyTable::kTheta, AnisoEnergyTable::kPhi, AnisoEnergyTable::kLevels, AnisoEnergyTable::kGrid};
}

// Recomputes `count` random nodes (all levels) and compares them with `table`.
bool spot_check(const AnisoEnergyTable &table, int count, std::string &problem) {
  if (count <= 0) return true;
  AnisoEnergyTable fresh;
  fresh.spec = table.spec;
  fresh.scale.assign(table.scale.size(), 1.0f);
  std::random_device device;
  std::uniform_int_distribution<int> pick(0, AnisoEnergyTable::kTheta * AnisoEnergyTable::kPhi - 1);
  for (int k = 0; k < count; ++k) {
    const int node = pick(device), ti = node / AnisoEnergyTable::kPhi, pi = node % AnisoEnergyTable::kPhi;
    fresh.build_node(ti, pi);
    for (int l = 0; l < AnisoEnergyTable::kLevels; ++l) {
      const size_t i = (static_cast<size_t>(l) * AnisoEnergyTable::kTheta + ti) * AnisoEnergyTable::kPhi + pi;
      if (std::fabs(static_cast<double>(table.scale[i]) - fresh.scale[i]) > kSpotCheckTolerance * fresh.scale[i]) {
        problem = "scale at theta_i " + std::to_string(ti) + ", phi_i " +
                  std::to_string(static_cast<int>(pi * AnisoEnergyTable::kPhiStepDeg)) + ", level " +
                  std::to_string(l) + " does not match its recomputation";
        return false;
      }
    }
  }
  return true;
}

bool plausible_scales(const AnisoEnergyTable &table, std::string &problem) {
  const size_t level_size = static_cast<size_t>(AnisoEnergyTable::kTheta) * AnisoEnergyTable::kPhi;
  for (size_t i = 0; i < table.scale.size(); ++i) {
    const float v = table.scale[i];
    if (!std::isfinite(v) || !(v > 0.0f)) {
      problem = "non-finite or non-positive values";
      return false;
    }
    if (i < level_size && v > 1.0f) {
      problem = "unblurred scale above 1 (the build only scales it down)";
      return false;
    }
  }
  return true;
}

}  // namespace

uint64_t aniso_energy_key(const AnisoSpec &spec) {
  const float phi_step = AnisoEnergyTable::kPhiStepDeg;
  const double resolution = AnisoEnergyTable::kEnergyResolution;
  return Fnv1a{}
      .add(kAnisoMagic)
      .add(kAnisoFormatVersion)
      .add(static_cast<int32_t>(spec.distribution))
      .add(spec.alpha_x)
      .add(spec.alpha_y)
      .add(spec.gamma_deg)
      .add(table_dims())
      .add(phi_step)
      .add(resolution)
      .h;
}

std::string aniso_energy_cache_path(const std::string &cache_dir, const AnisoSpec &spec) {
  return cache_entry_path(cache_dir, "glint_A_", aniso_energy_key(spec));
}

// File: magic, version, key, distribution, alpha_x, alpha_y, gamma, the four
// dimensions, the scales, then the HMAC-SHA256 of everything before it.
bool save_aniso_energy(const std::string &path, const AnisoEnergyTable &table, std::string &problem) {
  ByteWriter out;
  out.put_header(kAnisoMagic, kAnisoFormatVersion, aniso_energy_key(table.spec));
  out.put(static_cast<int32_t>(table.spec.distribution));
  out.put(table.spec.alpha_x);
  out.put(table.spec.alpha_y);
  out.put(table.spec.gamma_deg);
  out.put(table_dims());
  out.put(table.scale.data(), table.scale.size() * sizeof(float));
  problem = write_cache_blob(path, std::move(out.bytes));
  return problem.empty();
}

std::unique_ptr<AnisoEnergyTable> load_aniso_energy(const std::string &path, const AnisoSpec &spec,
                                                    std::string &problem, int spot_checks) {
  std::vector<unsigned char> bytes;
  problem = read_cache_file(path, bytes);
  if (!problem.empty()) return nullptr;
  ByteReader in{bytes};
  auto get = [&](void *p, size_t n) { return in.get(p, n); };
  int32_t dist = -1;
  std::array<int32_t, 4> dims{};
  auto table = std::make_unique<AnisoEnergyTable>();
  AnisoSpec &s = table->spec;
  if (!in.get_header(kAnisoMagic, kAnisoFormatVersion, aniso_energy_key(spec)) || !get(&dist, 4) ||
      !get(&s.alpha_x, 4) || !get(&s.alpha_y, 4) || !get(&s.gamma_deg, 4) || !get(dims.data(), sizeof(dims)) ||
      dims != table_dims()) {
    problem = "bad header (not an anisotropic glint energy table of this version and parameters)";
    return nullptr;
  }
  s.distribution = static_cast<mfa::Distribution>(dist);
  if (s.distribution != spec.distribution || s.alpha_x != spec.alpha_x || s.alpha_y != spec.alpha_y ||
      s.gamma_deg != spec.gamma_deg) {
    problem = "parameters differ from the requested table";
    return nullptr;
  }
  table->scale.assign(static_cast<size_t>(AnisoEnergyTable::kLevels) * AnisoEnergyTable::kTheta *
                          AnisoEnergyTable::kPhi,
                      0.0f);
  if (!get(table->scale.data(), table->scale.size() * sizeof(float))) {
    problem = "truncated";
    return nullptr;
  }
  problem = check_cache_mac(path, bytes, in.pos);
  if (!problem.empty()) return nullptr;
  if (!plausible_scales(*table, problem) || !spot_check(*table, spot_checks, problem)) return nullptr;
  table->loaded_from_cache = true;
  return table;
}

std::shared_ptr<const AnisoEnergyTable> acquire_aniso_energy(const AnisoSpec &spec, const GlimmerHostServices *host) {
  static std::mutex mutex;
  static std::map<AnisoSpec, std::weak_ptr<const AnisoEnergyTable>> shared;
  std::lock_guard<std::mutex> lock(mutex);
  if (auto table = shared[spec].lock()) return table;
  auto log = [&](int level, const std::string &msg) {
    if (host != nullptr && host->log != nullptr) host->log(host->host_data, level, msg.c_str());
  };
  const bool use_cache = host != nullptr && host->cache_dir != nullptr && host->cache_dir[0] != '\0';
  std::string path;
  std::unique_ptr<AnisoEnergyTable> table;
  if (use_cache) {
    path = aniso_energy_cache_path(host->cache_dir, spec);
    std::string problem;
    table = load_aniso_energy(path, spec, problem);
    if (!table && problem != "missing")
      log(GLIMMER_LOG_WARNING,
          "glint: cached anisotropic energy table " + path + " is unusable (" + problem + "); recomputing");
  }
  if (!table) {
    table = AnisoEnergyTable::build(spec, static_cast<int>(std::max(1u, std::thread::hardware_concurrency())));
    char msg[256];
    std::snprintf(msg, sizeof(msg),
                  "glint: precomputed anisotropic energy table (%s, alpha %.4g x %.4g, gamma %.3g deg) in %.3f s",
                  spec.distribution == mfa::Distribution::GGX ? "ggx" : "beckmann", spec.alpha_x, spec.alpha_y,
                  spec.gamma_deg, table->build_seconds);
    log(GLIMMER_LOG_INFO, msg);
    if (use_cache) {
      std::string problem;
      if (!save_aniso_energy(path, *table, problem))
        log(GLIMMER_LOG_WARNING, "glint: anisotropic energy table cache not written: " + problem);
    }
  }
  std::shared_ptr<const AnisoEnergyTable> result(std::move(table));
  shared[spec] = result;
  return result;
}

}  // namespace glimmer::plugin::glint
