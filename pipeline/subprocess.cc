#include "pipeline/subprocess.h"

#include <fcntl.h>
#include <spawn.h>
#include <sys/wait.h>
#include <unistd.h>

#include <cerrno>
#include <cstdlib>
#include <cstring>

#include <fmt/format.h>

#include "core/error.h"
#include "core/file_util.h"

extern char** environ;

namespace hmc {

namespace fs = std::filesystem;

fs::path SelfExecutable() { return fs::canonical("/proc/self/exe"); }

namespace {

// posix_spawn with stdout/stderr redirected to `out_path`/`err_path`
// ("" = inherited) and `env` on top of environ.
pid_t Spawn(const std::vector<std::string>& args, const std::map<std::string, std::string>& env,
            const std::string& out_path, const std::string& err_path, bool append) {
  HMC_CHECK(!args.empty());
  std::vector<std::string> env_text;
  for (char** e = environ; *e != nullptr; ++e) {
    const std::string entry = *e;
    const std::string name = entry.substr(0, entry.find('='));
    if (env.count(name) == 0) env_text.push_back(entry);
  }
  for (const auto& [name, value] : env) env_text.push_back(name + "=" + value);
  std::vector<char*> argv, envp;
  for (const std::string& a : args) argv.push_back(const_cast<char*>(a.c_str()));
  argv.push_back(nullptr);
  for (const std::string& e : env_text) envp.push_back(const_cast<char*>(e.c_str()));
  envp.push_back(nullptr);
  posix_spawn_file_actions_t actions;
  posix_spawn_file_actions_init(&actions);
  const int flags = O_WRONLY | O_CREAT | (append ? O_APPEND : O_TRUNC);
  if (!out_path.empty()) {
    posix_spawn_file_actions_addopen(&actions, 1, out_path.c_str(), flags, 0644);
  }
  if (!err_path.empty() && err_path == out_path) {
    posix_spawn_file_actions_adddup2(&actions, 1, 2);
  } else if (!err_path.empty()) {
    posix_spawn_file_actions_addopen(&actions, 2, err_path.c_str(), flags, 0644);
  }
  pid_t pid = -1;
  const int rc = posix_spawnp(&pid, argv[0], &actions, nullptr, argv.data(), envp.data());
  posix_spawn_file_actions_destroy(&actions);
  if (rc != 0) {
    throw InputError(fmt::format("cannot start {}: {}", args[0], std::strerror(rc)));
  }
  return pid;
}

}  // namespace

pid_t StartProcess(const std::vector<std::string>& args,
                   const std::map<std::string, std::string>& env, const fs::path& log) {
  return Spawn(args, env, log.string(), log.string(), true);
}

int WaitProcess(pid_t pid) {
  int status = 0;
  while (waitpid(pid, &status, 0) < 0) {
    if (errno != EINTR) return 127;
  }
  if (WIFEXITED(status)) return WEXITSTATUS(status);
  return WIFSIGNALED(status) ? 128 + WTERMSIG(status) : 127;
}

int CaptureProcess(const std::vector<std::string>& args, std::string* out, std::string* err) {
  char out_name[] = "/tmp/hmc_capture_out_XXXXXX";
  char err_name[] = "/tmp/hmc_capture_err_XXXXXX";
  const int out_fd = mkstemp(out_name);
  const int err_fd = mkstemp(err_name);
  if (out_fd >= 0) close(out_fd);
  if (err_fd >= 0) close(err_fd);
  int code = 127;
  try {
    code = WaitProcess(Spawn(args, {}, out_name, err_name, false));
  } catch (const InputError&) {
    code = 127;
  }
  std::error_code ec;
  if (out != nullptr) *out = fs::exists(out_name, ec) ? ReadFile(out_name) : "";
  if (err != nullptr) *err = fs::exists(err_name, ec) ? ReadFile(err_name) : "";
  fs::remove(out_name, ec);
  fs::remove(err_name, ec);
  return code;
}

bool OnPath(const std::string& program) {
  const char* path = std::getenv("PATH");
  if (path == nullptr) return false;
  const std::string paths = path;
  size_t start = 0;
  while (start <= paths.size()) {
    const size_t end = std::min(paths.find(':', start), paths.size());
    const fs::path candidate = fs::path(paths.substr(start, end - start)) / program;
    if (access(candidate.c_str(), X_OK) == 0) return true;
    start = end + 1;
  }
  return false;
}

}  // namespace hmc
