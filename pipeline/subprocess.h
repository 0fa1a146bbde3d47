// Child processes for `hmc batch` (docs/farm.md): the local scheduler runs
// each take as its own `hmc` process (a crash or a leak in one take cannot
// take the others down), and the SLURM scheduler talks to sbatch, squeue and
// scancel through their command lines, as a user would.
#pragma once

#include <sys/types.h>

#include <filesystem>
#include <map>
#include <string>
#include <vector>

namespace hmc {

// The running executable (/proc/self/exe, resolved): the `hmc` a batch
// starts for each take and writes into its job scripts.
std::filesystem::path SelfExecutable();

// Starts `args` (args[0] looked up on PATH) with `env` added to this
// process's environment, stdout and stderr appended to `log` ("" = this
// process's own). Returns the child's pid; throws InputError naming args[0]
// if it cannot be started.
pid_t StartProcess(const std::vector<std::string>& args,
                   const std::map<std::string, std::string>& env,
                   const std::filesystem::path& log);

// Waits for `pid`; its exit code, or 128 + the signal that ended it.
int WaitProcess(pid_t pid);

// Runs `args` to the end and returns its exit code (127: could not be
// started); what it printed on stdout in *out, stderr in *err (either may
// be null).
int CaptureProcess(const std::vector<std::string>& args, std::string* out,
                   std::string* err = nullptr);

// Whether `program` is an executable on PATH.
bool OnPath(const std::string& program);

}  // namespace hmc
