// A private single-node Slurm for the farm tests: generates a munge key and a
// slurm.conf on 127.0.0.1 (free ports, state in a temporary folder), starts munged,
// slurmctld and slurmd from the Debian packages, and stops every one of them again
// by the pid it recorded (destructor, and a watchdog should the test process die).
#pragma once

#include <netinet/in.h>
#include <signal.h>
#include <sys/socket.h>
#include <sys/wait.h>
#include <unistd.h>

#include <chrono>
#include <cstdio>
#include <cstdlib>
#include <filesystem>
#include <fstream>
#include <sstream>
#include <string>
#include <thread>
#include <vector>

#include "host/cli_runner.h"  // read_text

namespace glimmer::test {

class LocalSlurm {
 public:
  // Why the cluster could not be started ("" when it runs); `missing_packages` says the
  // failure is an absent installation (the test is skipped), not a broken start.
  std::string problem;
  bool missing_packages = false;

  explicit LocalSlurm(const std::filesystem::path &dir) : dir_(dir) {
    for (const char *tool : {"munged", "mungekey", "slurmctld", "slurmd", "sbatch", "scontrol"})
      if (run(std::string("command -v ") + tool + " > /dev/null") != 0) {
        problem = std::string(tool) + " not installed (Debian packages slurm-wlm, munge: make deps)";
        missing_packages = true;
        return;
      }
    if (::geteuid() != 0) {
      problem = "slurmd must run as root to launch jobs; run the test as root";
      missing_packages = true;
      return;
    }
    namespace fs = std::filesystem;
    fs::remove_all(dir_);
    for (const char *sub : {"munge", "state", "spool", "log"}) fs::create_directories(dir_ / sub);
    fs::permissions(dir_ / "munge", fs::perms::owner_all | fs::perms::group_exec | fs::perms::others_exec);
    const std::string d = dir_.string();
    if (run("mungekey --create --keyfile=" + d + "/munge/munge.key > " + d + "/log/mungekey.log 2>&1") != 0) {
      problem = "mungekey failed: " + read_text(dir_ / "log/mungekey.log");
      return;
    }
    socket_ = d + "/munge/munge.sock";
    if (run("munged --force -S " + socket_ + " --key-file=" + d + "/munge/munge.key --log-file=" + d +
            "/log/munged.log --pid-file=" + d + "/munge/munged.pid --seed-file=" + d + "/munge/munged.seed") != 0) {
      problem = "munged did not start: " + read_text(dir_ / "log/munged.log");
      return;
    }
    pid_files_.push_back(dir_ / "munge/munged.pid");
    write_conf();
    ::setenv("SLURM_CONF", conf().c_str(), 1);
    if (run("slurmctld -f " + conf()) != 0) {
      problem = "slurmctld did not start: " + read_text(dir_ / "log/slurmctld.log");
      return;
    }
    pid_files_.push_back(dir_ / "slurmctld.pid");
    if (run("slurmd -f " + conf() + " -N " + node_) != 0) {
      problem = "slurmd did not start: " + read_text(dir_ / "log/slurmd.log");
      return;
    }
    pid_files_.push_back(dir_ / "slurmd.pid");
    // Ready when the node reports idle.
    const auto deadline = std::chrono::steady_clock::now() + std::chrono::seconds(60);
    while (capture("sinfo -h -N -o %T 2>/dev/null").find("idle") == std::string::npos) {
      if (std::chrono::steady_clock::now() > deadline) {
        problem = "the node never became idle: " + read_text(dir_ / "log/slurmd.log") + read_text(dir_ / "log/slurmctld.log");
        return;
      }
      std::this_thread::sleep_for(std::chrono::milliseconds(200));
    }
    start_watchdog();
  }

  ~LocalSlurm() { stop(); }
  LocalSlurm(const LocalSlurm &) = delete;
  LocalSlurm &operator=(const LocalSlurm &) = delete;

  std::string conf() const { return (dir_ / "slurm.conf").string(); }
  int cpus() const { return cpus_; }

  // Job state from scontrol (COMPLETED, FAILED, PENDING, ...; "" when unknown); for an
  // array, the state of every task joined by spaces.
  std::string job_state(const std::string &id) const {
    const std::string text = capture("scontrol -o show job " + id + " 2>/dev/null");
    std::string states;
    for (size_t at = text.find("JobState="); at != std::string::npos; at = text.find("JobState=", at + 1)) {
      const size_t end = text.find(' ', at);
      states += (states.empty() ? "" : " ") + text.substr(at + 9, end - at - 9);
    }
    if (text.find("DependencyNeverSatisfied") != std::string::npos) states += " DependencyNeverSatisfied";
    return states;
  }

  // Waits until job `id` has ended; returns its final state.
  std::string wait(const std::string &id, int seconds) const {
    const auto deadline = std::chrono::steady_clock::now() + std::chrono::seconds(seconds);
    for (;;) {
      const std::string s = job_state(id);
      const bool running = s.find("PENDING") != std::string::npos || s.find("RUNNING") != std::string::npos ||
                           s.find("CONFIGURING") != std::string::npos || s.find("COMPLETING") != std::string::npos;
      if (s.find("DependencyNeverSatisfied") != std::string::npos) return s;
      if (!s.empty() && !running) return s;
      if (std::chrono::steady_clock::now() > deadline) return "TIMEOUT(test) " + s;
      std::this_thread::sleep_for(std::chrono::milliseconds(250));
    }
  }

  // Cancels every job of this cluster, then stops slurmd, slurmctld and munged.
  void stop() {
    if (pid_files_.empty()) return;
    run("squeue -h -o %A 2>/dev/null | xargs -r scancel 2>/dev/null");
    for (auto it = pid_files_.rbegin(); it != pid_files_.rend(); ++it) terminate(*it);
    pid_files_.clear();
    if (watchdog_ > 0) {
      ::kill(watchdog_, SIGKILL);
      ::waitpid(watchdog_, nullptr, 0);
      watchdog_ = 0;
    }
  }

  static std::string capture(const std::string &cmd) {
    std::string out;
    if (FILE *p = ::popen(cmd.c_str(), "r")) {
      char buffer[4096];
      size_t n;
      while ((n = std::fread(buffer, 1, sizeof buffer, p)) > 0) out.append(buffer, n);
      ::pclose(p);
    }
    return out;
  }


 private:
  std::filesystem::path dir_;
  std::string socket_, node_;
  int cpus_ = 1;
  std::vector<std::filesystem::path> pid_files_;
  pid_t watchdog_ = 0;

  static int run(const std::string &cmd) { return std::system(cmd.c_str()); }

  static int free_port() {
    const int s = ::socket(AF_INET, SOCK_STREAM, 0);
    sockaddr_in a{};
    a.sin_family = AF_INET;
    a.sin_addr.s_addr = htonl(INADDR_LOOPBACK);
    socklen_t len = sizeof a;
    int port = 0;
    if (::bind(s, reinterpret_cast<sockaddr *>(&a), sizeof a) == 0 &&
        ::getsockname(s, reinterpret_cast<sockaddr *>(&a), &len) == 0)
      port = ntohs(a.sin_port);
    ::close(s);
    return port;
  }

  void write_conf() {
    char host[256] = {0};
    ::gethostname(host, sizeof host - 1);
    node_ = std::string(host).substr(0, std::string(host).find('.'));
    cpus_ = std::max(1, static_cast<int>(std::thread::hardware_concurrency()));
    const std::string d = dir_.string();
    std::ofstream c(conf());
    c << "# Generated by tests/bridge/local_slurm.h: one node on the loopback, state in " << d << "\n"
      << "ClusterName=glimmertest\nSlurmctldHost=" << node_ << "(127.0.0.1)\n"
      << "SlurmctldPort=" << free_port() << "\nSlurmdPort=" << free_port() << "\n"
      << "SlurmUser=root\nSlurmdUser=root\nAuthType=auth/munge\nCredType=cred/munge\nAuthInfo=socket=" << socket_
      << "\nStateSaveLocation=" << d << "/state\nSlurmdSpoolDir=" << d << "/spool\n"
      << "SlurmctldPidFile=" << d << "/slurmctld.pid\nSlurmdPidFile=" << d << "/slurmd.pid\n"
      << "SlurmctldLogFile=" << d << "/log/slurmctld.log\nSlurmdLogFile=" << d << "/log/slurmd.log\n"
      << "ProctrackType=proctrack/linuxproc\nTaskPlugin=task/none\nJobAcctGatherType=jobacct_gather/none\n"
      << "AccountingStorageType=accounting_storage/none\nJobCompType=jobcomp/none\nMpiDefault=none\n"
      << "SchedulerType=sched/builtin\nSelectType=select/cons_tres\nSelectTypeParameters=CR_CPU\n"
      << "ReturnToService=2\nMinJobAge=600\nSlurmctldDebug=info\nSlurmdDebug=info\n"
      << "NodeName=" << node_ << " NodeAddr=127.0.0.1 CPUs=" << cpus_ << " State=UNKNOWN\n"
      << "PartitionName=glimmer Nodes=ALL Default=YES MaxTime=INFINITE State=UP\n";
  }

  static pid_t read_pid(const std::filesystem::path &file) {
    std::ifstream in(file);
    long pid = 0;
    in >> pid;
    return static_cast<pid_t>(pid);
  }

  // SIGTERM, up to 10 s to exit, then SIGKILL: the daemon started here, by its recorded pid.
  static void terminate(const std::filesystem::path &pid_file) {
    const pid_t pid = read_pid(pid_file);
    if (pid <= 1) return;
    ::kill(pid, SIGTERM);
    for (int k = 0; k < 100 && ::kill(pid, 0) == 0; ++k) std::this_thread::sleep_for(std::chrono::milliseconds(100));
    if (::kill(pid, 0) == 0) ::kill(pid, SIGKILL);
  }

  // Stops the daemons should this process die without running the destructor.
  void start_watchdog() {
    std::string pids;
    for (const auto &f : pid_files_) pids += " " + std::to_string(read_pid(f));
    const std::string script =
        "while kill -0 " + std::to_string(::getpid()) + " 2>/dev/null; do sleep 2; done; kill" + pids + " 2>/dev/null";
    watchdog_ = ::fork();
    if (watchdog_ == 0) {
      ::setsid();
      ::execl("/bin/sh", "sh", "-c", script.c_str(), static_cast<char *>(nullptr));
      ::_exit(127);
    }
  }
};

}  // namespace glimmer::test
