// `glimmer precompute energy`: Monte Carlo generation of the GGX
// multiple-scattering energy tables (plugin/tables/microfacet_energy_data.cpp).
//  - E(mu, alpha), E_avg(alpha): Fresnel-free single-scatter conductor albedo,
//    stratified visible-normal sampling (strata^2 samples per cell).
//  - E(mu, alpha, eta), E_avg for the dielectric (R + T), wi outside (eta) and
//    inside (1 / eta): same estimator.
//  - E_Fms(mu, alpha, F0) = P(F0) / (1 - h F0) with a cubic P (Hill 2022;
//    h = (1 - E) / 2, see glimmer/microfacet_walk.h): Heitz 2016 random walks
//    carrying the Fresnel-split coefficients e[0..N-1]; walks of order >= 2
//    give E_ms; the average coefficients are rescaled so that E_Fms(F0 = 1)
//    equals 1 - E (energy conservation of the Fresnel-free walk: a ratio
//    estimator), then P is refit minimizing the error relative to E_Fms.
//  - The bounce-tint energy T(c) = sum_k p_k c^k (k >= 2 bounces, each tinted by a
//    constant c: Cycles' Multiscatter GGX colour) from the same walks, stored and
//    refit the same way with h = 0.6 (1 - E).
// Output: C++ source with the command line and sample counts in its header.
#include <tbb/parallel_for.h>

#include <algorithm>
#include <array>
#include <chrono>
#include <cstdio>
#include <filesystem>
#include <sstream>
#include <string>
#include <vector>

#include "cli/commands.h"
#include "glimmer/atomic_file.h"
#include "glimmer/microfacet_energy_grid.h"
#include "glimmer/microfacet_walk.h"
#include "glimmer/rng.h"

namespace glimmer::cli {

namespace {

using namespace glimmer::microfacet;
namespace grid = glimmer::microfacet::energy_grid;

constexpr int kSplitTerms = kFresnelSplitTerms;

// E_avg = 2 int_0^1 E(mu) mu dmu = int_0^1 4 t^3 E(t^2) dt (mu = t^2): trapezoid
// on the nodes, normalized by the same rule applied to E = 1 (exact for constant E).
float average_over_mu(const float *e) {
  double sum = 0.0, norm = 0.0;
  const double dt = 1.0 / (grid::kMuCount - 1);
  for (int i = 0; i < grid::kMuCount; ++i) {
    const double t = i * dt;
    const double w = ((i == 0 || i == grid::kMuCount - 1) ? 0.5 : 1.0) * 4.0 * t * t * t;
    sum += w * e[i];
    norm += w;
  }
  return float(sum / norm);
}

std::string fmt(float v) {
  char buf[32];
  std::snprintf(buf, sizeof buf, "%.5f", double(v));
  std::string s(buf);
  if (s.rfind("0.", 0) == 0) s.erase(0, 1);           // ".12345"
  else if (s.rfind("-0.", 0) == 0) s.erase(1, 1);     // "-.12345"
  while (s.size() > 2 && s.back() == '0') s.pop_back();
  if (s.back() == '.') s.pop_back();
  if (s.empty() || s == "-" || s == "." || s == ".0" || s == "-.0" || s == "-.") s = "0";
  return s;
}

// Seven significant digits (float precision): the E_Fms coefficients of
// smooth, low-roughness cells are tiny and their relative accuracy matters.
std::string fmt_significant(float v) {
  char buf[32];
  std::snprintf(buf, sizeof buf, "%.7g", double(v));
  return buf;
}

void write_rows(std::ostream &out, const float *data, size_t count, size_t per_line,
                std::string (*format)(float) = fmt) {
  for (size_t i = 0; i < count; ++i) {
    out << format(data[i]) << ',';
    if ((i + 1) % per_line == 0 || i + 1 == count) out << '\n';
  }
}

struct EnergyOptions {
  std::string output;
  int strata = 48;
  int walks = 32768;
  uint32_t seed = 1;
};

int run_energy(const EnergyOptions &opt, const std::string &command_line) {
  if (opt.strata < 2 || opt.walks < 16) throw CliError(kExitBadInput, "--strata must be >= 2 and --walks >= 16");
  {  // before the (long) computation: the output folder must exist
    const std::filesystem::path target(opt.output);
    const std::filesystem::path dir = target.has_parent_path() ? target.parent_path() : ".";
    std::error_code ec;
    if (!std::filesystem::is_directory(dir, ec))
      throw CliError(kExitBadInput, "cannot write --output '" + opt.output + "': folder '" + dir.string() +
                                        "' does not exist");
  }
  const auto start = std::chrono::steady_clock::now();
  constexpr int nm = grid::kMuCount, na = grid::kAlphaCount, ne = grid::kEtaCount;
  // Grazing cells (mu < 0.1) have the largest weight variance: twice the strata per axis.
  auto strata_for = [&](int m) { return grid::mu_of_node(m) < 0.1f ? 2 * opt.strata : opt.strata; };
  std::vector<float> E(na * nm), Eavg(na), Fms(na * nm * 4), Tint(na * nm * 4);
  std::vector<double> fit_errors(na * nm, 0.0), tint_fit_errors(na * nm, 0.0);
  std::vector<float> G(ne * na * nm), Ginv(ne * na * nm), Gavg(ne * na), Ginvavg(ne * na);

  // Conductor single scattering, then the random walks per (alpha, mu).
  tbb::parallel_for(0, na * nm, [&](int cell) {
    const int a = cell / nm, m = cell % nm;
    WalkRng rng(hash_u32x3(opt.seed, 1u, uint32_t(cell)));
    E[cell] = float(single_scatter_albedo_conductor(Distribution::GGX, grid::mu_of_node(m), grid::alpha_of_node(a),
                                                    strata_for(m), rng));
    E[cell] = std::stof(fmt(E[cell]));  // the value the table will hold (E_Fms(1) = 1 - E exactly)
  });
  for (int a = 0; a < na; ++a) Eavg[a] = average_over_mu(&E[a * nm]);

  tbb::parallel_for(0, na * nm, [&](int cell) {
    const int a = cell / nm, m = cell % nm;
    const float mu = grid::mu_of_node(m), alpha = grid::alpha_of_node(a);
    WalkRng rng(hash_u32x3(opt.seed, 2u, uint32_t(cell)));
    // Ratio estimator: scaled so that E_Fms(F0 = 1) = 1 - E exactly (white furnace).
    std::array<double, kSplitTerms> tint{};
    const auto w = fresnel_split_polynomial(mu, alpha, opt.walks, 1.0 - double(E[cell]), rng, &tint);
    double fit_error = 0.0, tint_error = 0.0;
    const auto c = fit_fresnel_split_cubic(w, double(E[cell]), &fit_error);
    const auto t = fit_fresnel_split_cubic(tint, double(E[cell]), &tint_error, kBounceTintTail);
    for (int k = 0; k < 4; ++k) Fms[cell * 4 + k] = float(c[k]), Tint[cell * 4 + k] = float(t[k]);
    fit_errors[cell] = fit_error;
    tint_fit_errors[cell] = tint_error;
  });

  // Dielectric R + T, both sides.
  tbb::parallel_for(0, ne * na * nm, [&](int cell) {
    const int e = cell / (na * nm), a = (cell / nm) % na, m = cell % nm;
    const float eta = grid::eta_of_node(e), mu = grid::mu_of_node(m), alpha = grid::alpha_of_node(a);
    WalkRng rng(hash_u32x3(opt.seed, 3u, uint32_t(cell)));
    G[cell] = float(single_scatter_albedo_dielectric(Distribution::GGX, mu, alpha, eta, strata_for(m), rng));
    Ginv[cell] = float(single_scatter_albedo_dielectric(Distribution::GGX, mu, alpha, 1.0f / eta, strata_for(m), rng));
  });
  for (int i = 0; i < ne * na; ++i) {
    Gavg[i] = average_over_mu(&G[i * nm]);
    Ginvavg[i] = average_over_mu(&Ginv[i * nm]);
  }
  const double seconds = std::chrono::duration<double>(std::chrono::steady_clock::now() - start).count();
  char fit_error_text[32], tint_error_text[32];
  std::snprintf(fit_error_text, sizeof fit_error_text, "%.3f %%",
                100.0 * *std::max_element(fit_errors.begin(), fit_errors.end()));
  std::snprintf(tint_error_text, sizeof tint_error_text, "%.3f %%",
                100.0 * *std::max_element(tint_fit_errors.begin(), tint_fit_errors.end()));

  std::ostringstream out;
  out << "// GENERATED by `glimmer precompute energy`; do not edit.\n"
      << "// Command: " << command_line << "\n"
      << "// Samples: single-scatter albedo cells use " << opt.strata << "x" << opt.strata
      << " stratified visible-normal samples (" << opt.strata * opt.strata << " per cell; "
      << 4 * opt.strata * opt.strata << " for mu < 0.1);\n"
      << "// E_Fms cells use " << opt.walks << " Heitz 2016 random walks each, " << kSplitTerms
      << " Fresnel-split terms, ratio-scaled to 1 - E;\n"
      << "// E_Fms(F0) = P(F0) / (1 - " << kFresnelSplitTail
      << " (1 - E) F0), cubic P refit for the minimax error relative to E_Fms over F0 in\n"
      << "// [0, 1] (F0 = 1 exact); largest fit error over all cells " << fit_error_text << ".\n"
      << "// Bounce-tint energy T(c) = P(c) / (1 - " << kBounceTintTail
      << " (1 - E) c) from the same walks' bounce orders, same refit;\n"
      << "// largest fit error " << tint_error_text << ".\n"
      << "// Grid: glimmer/microfacet_energy_grid.h (mu " << nm << " x alpha " << na << " x eta " << ne << "), seed "
      << opt.seed << ", generated in " << int(seconds + 0.5) << " s.\n"
      << "#include \"tables/microfacet_energy.h\"\n\nnamespace glimmer::tables {\n\n";
  out << "const float kGgxE[grid::kAlphaCount][grid::kMuCount] = {\n";
  write_rows(out, E.data(), E.size(), nm);
  out << "};\n\nconst float kGgxEAvg[grid::kAlphaCount] = {\n";
  write_rows(out, Eavg.data(), Eavg.size(), 16);
  out << "};\n\nconst float kGgxFms[grid::kAlphaCount][grid::kMuCount][4] = {\n";
  write_rows(out, Fms.data(), Fms.size(), 16, fmt_significant);
  out << "};\n\nconst float kGgxTintMs[grid::kAlphaCount][grid::kMuCount][4] = {\n";
  write_rows(out, Tint.data(), Tint.size(), 16, fmt_significant);
  out << "};\n\nconst float kGgxGlassE[grid::kEtaCount][grid::kAlphaCount][grid::kMuCount] = {\n";
  write_rows(out, G.data(), G.size(), nm);
  out << "};\n\nconst float kGgxGlassInvE[grid::kEtaCount][grid::kAlphaCount][grid::kMuCount] = {\n";
  write_rows(out, Ginv.data(), Ginv.size(), nm);
  out << "};\n\nconst float kGgxGlassEAvg[grid::kEtaCount][grid::kAlphaCount] = {\n";
  write_rows(out, Gavg.data(), Gavg.size(), na);
  out << "};\n\nconst float kGgxGlassInvEAvg[grid::kEtaCount][grid::kAlphaCount] = {\n";
  write_rows(out, Ginvavg.data(), Ginvavg.size(), na);
  out << "};\n\n}  // namespace glimmer::tables\n";

  if (const std::string problem = write_file_atomically(opt.output, out.str()); !problem.empty())
    throw CliError(kExitBadInput, "cannot write --output: " + problem);
  std::printf("wrote %s (%zu bytes) in %.1f s\n", opt.output.c_str(), out.str().size(), seconds);
  return kExitOk;
}

}  // namespace

void add_precompute_command(CLI::App &app, CliContext &ctx) {
  auto *pre = app.add_subcommand("precompute", "generate precomputed tables as C++ source");
  pre->require_subcommand(1);
  auto opt = std::make_shared<EnergyOptions>();
  auto *energy = pre->add_subcommand("energy", "GGX multiple-scattering energy tables (Monte Carlo)");
  energy->add_option("-o,--output", opt->output, "output .cpp (e.g. plugin/tables/microfacet_energy_data.cpp)")
      ->required();
  energy->add_option("--strata", opt->strata, "single-scatter cells: strata x strata visible-normal samples")
      ->capture_default_str();
  energy->add_option("--walks", opt->walks, "random walks per E_Fms cell")->capture_default_str();
  energy->add_option("--seed", opt->seed, "random seed")->capture_default_str();
  energy->callback([opt, &ctx]() {
    const std::string command = "glimmer precompute energy --strata " + std::to_string(opt->strata) + " --walks " +
                                std::to_string(opt->walks) + " --seed " + std::to_string(opt->seed) +
                                " --output plugin/tables/microfacet_energy_data.cpp";
    ctx.exit_code = run_energy(*opt, command);
  });
}

}  // namespace glimmer::cli
