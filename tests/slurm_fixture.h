// A real one-node SLURM cluster on localhost for the tests of `hmc batch
// --scheduler slurm` (docs/farm.md, "The test cluster"): munged, slurmctld
// and slurmd of Debian's slurm-wlm and munge, started from a temporary
// folder with their own slurm.conf, free ports and munge key (nothing in
// /etc is read or written), and stopped by their pids. SLURM_CONF is set
// in this process for as long as the cluster runs, so sbatch/squeue and
// every job see it.
#pragma once

#include <netinet/in.h>
#include <signal.h>
#include <sys/socket.h>
#include <sys/stat.h>
#include <sys/wait.h>
#include <unistd.h>

#include <chrono>
#include <cstdlib>
#include <filesystem>
#include <fstream>
#include <random>
#include <string>
#include <thread>
#include <vector>

#include <fmt/format.h>

#include "pipeline/subprocess.h"

namespace hmc {

class SlurmCluster {
 public:
  // "" when the daemons and clients are installed; else what is missing.
  static std::string Missing() {
    std::string missing;
    for (const char* program : {"munged", "slurmctld", "slurmd", "sbatch", "squeue", "scancel",
                                "sinfo"}) {
      const bool found = OnPath(program) ||
                         access((std::string("/usr/sbin/") + program).c_str(), X_OK) == 0;
      if (!found) missing += std::string(missing.empty() ? "" : ", ") + program;
    }
    return missing;
  }

  // Starts the cluster in `dir` (kept short: munge's socket path must fit
  // in 108 bytes). Ok() says whether the node came up; Error() why not.
  explicit SlurmCluster(const std::filesystem::path& dir) : dir_(dir) {
    namespace fs = std::filesystem;
    for (const char* sub : {"munge", "state", "spool", "log", "run"}) {
      fs::create_directories(dir_ / sub);
    }
    // munged wants o+x above its socket and no group-writable key folder.
    chmod(dir_.c_str(), 0755);
    chmod((dir_ / "munge").c_str(), 0755);
    {
      std::mt19937_64 random(std::random_device{}());
      std::ofstream key(dir_ / "munge" / "munge.key", std::ios::binary);
      for (int i = 0; i < 1024; ++i) key.put(static_cast<char>(random() & 0xff));
    }
    chmod((dir_ / "munge" / "munge.key").c_str(), 0600);
    const std::string d = dir_.string();
    pids_.push_back(StartProcess(
        {Daemon("munged"), "-F", "--origin=127.0.0.1", "--key-file=" + d + "/munge/munge.key",
         "--socket=" + d + "/munge/munge.sock", "--pid-file=" + d + "/run/munged.pid",
         "--log-file=" + d + "/log/munged.log", "--seed-file=" + d + "/munge/munge.seed"},
        {}, dir_ / "log" / "munged.out"));
    if (!WaitFor([&] { return fs::exists(dir_ / "munge" / "munge.sock"); }, 10)) {
      error_ = "munged did not start (" + d + "/log/munged.log)";
      return;
    }
    const std::string user = User();
    const std::string conf = fmt::format(
        "ClusterName=fixture\nSlurmctldHost=localhost\nSlurmctldPort={}\nSlurmdPort={}\n"
        "SlurmUser={}\nSlurmdUser={}\nAuthType=auth/munge\nCredType=cred/munge\n"
        "AuthInfo=socket={}/munge/munge.sock\nStateSaveLocation={}/state\n"
        "SlurmdSpoolDir={}/spool\nSlurmctldPidFile={}/run/slurmctld.pid\n"
        "SlurmdPidFile={}/run/slurmd.pid\nSlurmctldLogFile={}/log/slurmctld.log\n"
        "SlurmdLogFile={}/log/slurmd.log\nProctrackType=proctrack/linuxproc\n"
        "TaskPlugin=task/none\nSelectType=select/cons_tres\nSelectTypeParameters=CR_Core\n"
        "SchedulerParameters=batch_sched_delay=0\nDependencyParameters=kill_invalid_depend\n"
        "MailProg=/bin/true\nReturnToService=2\nMpiDefault=none\n"
        "JobAcctGatherType=jobacct_gather/none\nAccountingStorageType=accounting_storage/none\n"
        "JobCompType=jobcomp/none\nNodeName=localhost NodeAddr=127.0.0.1 CPUs={}\n"
        "PartitionName=debug Nodes=localhost Default=YES MaxTime=INFINITE State=UP\n",
        FreePort(), FreePort(), user, user, d, d, d, d, d, d, d,
        std::max(1u, std::thread::hardware_concurrency()));
    std::ofstream(dir_ / "slurm.conf") << conf;
    setenv("SLURM_CONF", (dir_ / "slurm.conf").c_str(), 1);
    pids_.push_back(StartProcess({Daemon("slurmctld"), "-D", "-i"}, {},
                                 dir_ / "log" / "slurmctld.out"));
    pids_.push_back(StartProcess({Daemon("slurmd"), "-D", "-N", "localhost"}, {},
                                 dir_ / "log" / "slurmd.out"));
    if (!WaitFor(
            [] {
              std::string out;
              CaptureProcess({"sinfo", "-h", "-n", "localhost", "-o", "%T"}, &out);
              return out.rfind("idle", 0) == 0;
            },
            30)) {
      error_ = "the node did not come up idle within 30 s (" + d + "/log/)";
    }
  }

  ~SlurmCluster() {
    // Jobs first: slurmd's end would leave slurmstepd and the jobs running.
    std::string user = User();
    CaptureProcess({"scancel", "-u", user}, nullptr);
    WaitFor(
        [] {
          std::string out;
          return CaptureProcess({"squeue", "-h"}, &out) != 0 || out.empty();
        },
        20);
    // slurmd, slurmctld, munged: the reverse of their start.
    for (auto it = pids_.rbegin(); it != pids_.rend(); ++it) {
      kill(*it, SIGTERM);
      const auto start = std::chrono::steady_clock::now();
      while (waitpid(*it, nullptr, WNOHANG) == 0) {
        if (std::chrono::steady_clock::now() - start > std::chrono::seconds(10)) {
          kill(*it, SIGKILL);
          waitpid(*it, nullptr, 0);
          break;
        }
        std::this_thread::sleep_for(std::chrono::milliseconds(20));
      }
    }
    unsetenv("SLURM_CONF");
    std::error_code ec;
    std::filesystem::remove_all(dir_, ec);
  }

  SlurmCluster(const SlurmCluster&) = delete;
  SlurmCluster& operator=(const SlurmCluster&) = delete;

  bool Ok() const { return error_.empty(); }
  const std::string& Error() const { return error_; }

 private:
  static std::string Daemon(const std::string& name) {
    return OnPath(name) ? name : "/usr/sbin/" + name;
  }
  static std::string User() {
    std::string out;
    CaptureProcess({"id", "-un"}, &out);
    while (!out.empty() && (out.back() == '\n' || out.back() == ' ')) out.pop_back();
    return out;
  }
  // A TCP port free now on 127.0.0.1 (the kernel's pick).
  static int FreePort() {
    const int fd = socket(AF_INET, SOCK_STREAM, 0);
    sockaddr_in address{};
    address.sin_family = AF_INET;
    address.sin_addr.s_addr = htonl(INADDR_LOOPBACK);
    address.sin_port = 0;
    socklen_t length = sizeof address;
    bind(fd, reinterpret_cast<sockaddr*>(&address), sizeof address);
    getsockname(fd, reinterpret_cast<sockaddr*>(&address), &length);
    close(fd);
    return ntohs(address.sin_port);
  }
  template <typename Condition>
  static bool WaitFor(const Condition& condition, double seconds) {
    const auto end = std::chrono::steady_clock::now() + std::chrono::duration<double>(seconds);
    while (std::chrono::steady_clock::now() < end) {
      if (condition()) return true;
      std::this_thread::sleep_for(std::chrono::milliseconds(100));
    }
    return condition();
  }

  std::filesystem::path dir_;
  std::vector<pid_t> pids_;
  std::string error_;
};

}  // namespace hmc
