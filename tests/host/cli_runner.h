// Runs the `glimmer` executable in a shell for the CLI tests and captures its
// exit code, stdout and stderr. The environment is controlled explicitly:
// GLIMMER_PLUGIN_PATH is removed unless the test sets it.
#pragma once

#include <sys/wait.h>
#include <unistd.h>

#include <atomic>
#include <cstdlib>
#include <filesystem>
#include <fstream>
#include <sstream>
#include <string>
#include <vector>

namespace glimmer::test {

struct CliRun {
  int exit_code = -1;
  std::string out, err;
};

inline std::string shell_quote(const std::string &s) {
  std::string q = "'";
  for (char c : s) {
    if (c == '\'') q += "'\\''";
    else q += c;
  }
  q += '\'';
  return q;
}

inline std::string read_text(const std::filesystem::path &path) {
  std::ifstream in(path);
  std::stringstream s;
  s << in.rdbuf();
  return s.str();
}

// `env_assignments` like {"GLIMMER_PLUGIN_PATH=/x"}; `executable` defaults to
// the CLI under test.
inline CliRun run_cli(const std::vector<std::string> &args, const std::vector<std::string> &env_assignments = {},
                      const std::string &executable = GLIMMER_TEST_CLI_PATH) {
  namespace fs = std::filesystem;
  static std::atomic<int> counter{0};
  const fs::path dir = fs::path(GLIMMER_TEST_BINARY_DIR) / "cli_runs";
  fs::create_directories(dir);
  const std::string stem = std::to_string(::getpid()) + "_" + std::to_string(counter++);
  const fs::path out = dir / (stem + ".out"), err = dir / (stem + ".err");
  std::string cmd = "env -u GLIMMER_PLUGIN_PATH";
  auto append = [&cmd](const std::string &word) {
    cmd += ' ';
    cmd += shell_quote(word);
  };
  for (const auto &e : env_assignments) append(e);
  append(executable);
  for (const auto &a : args) append(a);
  cmd += " >";
  append(out.string());
  cmd += " 2>";
  append(err.string());
  const int status = std::system(cmd.c_str());
  CliRun run;
  run.exit_code = WIFEXITED(status) ? WEXITSTATUS(status) : -1;
  run.out = read_text(out);
  run.err = read_text(err);
  fs::remove(out);
  fs::remove(err);
  return run;
}

}  // namespace glimmer::test
