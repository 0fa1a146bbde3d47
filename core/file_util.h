// Atomic file writes: every output is written to a temporary file in the
// target's folder and renamed into place, so a failed or interrupted write
// never leaves a half-written file and never destroys the previous one.
#pragma once

#include <filesystem>
#include <functional>
#include <iosfwd>
#include <string>
#include <string_view>
#include <vector>

namespace hmc {

// Calls write(stream) on a temporary file beside `path`, then renames it to
// `path`. If `write` throws, the temporary is removed and `path` untouched.
// The temporary is flushed to disk (fsync) before the rename and the folder
// after it, so the new name never points at data that did not reach the
// disk; temporaries of the same output left by a killed process
// (`.NAME.tmp.PID.N` of a PID that no longer runs) are removed first.
// Throws InputError naming `path` when the file cannot be written.
void WriteFileAtomic(const std::filesystem::path& path,
                     const std::function<void(std::ostream&)>& write,
                     bool binary = false);
void WriteFileAtomic(const std::filesystem::path& path,
                     std::string_view contents);

// Reads a whole file; throws InputError naming `path` and what it is if it
// is not a readable regular file (missing, a folder, a FIFO or device, a
// loop of symbolic links).
std::string ReadFile(const std::filesystem::path& path);

// "" for a regular file (or a link to one); otherwise what `path` is, as
// the end of a sentence: "does not exist", "is a folder, not a file", ...
// For input checks that must not throw a raw filesystem error.
std::string DescribeUnreadable(const std::filesystem::path& path);

// Creates `dir` (and parents); throws InputError if it cannot.
void EnsureDirectory(const std::filesystem::path& dir);

// One input path of a command (a file or a folder) and its flag, for
// CheckOutputApartFromInputs.
struct InputPath {
  std::filesystem::path path;  // empty: not given, skipped
  std::string flag;            // "--shot"
};

// Checks an output path before any work is done (docs/reliability.md):
// creates its folder (and parents), and throws InputError naming `path` and
// `what` (the flag: "--diagnostics") if it lies inside an actor package
// (decided before any folder is created; `hmc index --into_package` is the
// one writer into a package, and does not come here), if that folder
// cannot be created or written, or if `path` is an existing folder (a file
// output) or an existing file (a folder output, folder = true).
// Before that, CheckOutputApartFromInputs with the command's `inputs`.
void PrepareOutputPath(const std::filesystem::path& path,
                       const std::string& what, bool folder = false,
                       const std::vector<InputPath>& inputs = {});

// The one input/output overlap check of every command (docs/reliability.md):
// throws InputError naming both flags when `output` is one of `inputs`,
// lies inside an input folder (`hmc run --shot S --out S/cam0`, `hmc
// calibrate --out S/calibration.yaml`: files beside --out would land in the
// shot too), or is a folder that holds an input. Paths are compared after
// resolving links and `..`. Also refuses a path that is not valid UTF-8
// (the JSON summaries record paths): `what` names the output's flag.
void CheckOutputApartFromInputs(const std::filesystem::path& output, const std::string& what,
                                const std::vector<InputPath>& inputs);

// The actor package (a folder holding actor.yaml) that `path` is or lies
// inside, or "" when none: outputs are never written into a package.
std::filesystem::path EnclosingActorPackage(const std::filesystem::path& path);

// Writes a whole folder or nothing: write(tmp) fills a fresh temporary
// folder beside `dir` (`.NAME.tmp.PID.N`), which is then renamed to `dir`
// (a previous `dir` is removed only after the new one is complete). `dir`
// must be missing, empty, or a folder this function wrote before for the
// same `what` (it holds `.hmc_output` naming it); anything else, and a
// `dir` inside an actor package, is refused with an InputError before write
// runs. Stale
// temporary folders of killed runs are removed. what: the command
// ("hmc synth shot").
void WriteFolderAtomic(const std::filesystem::path& dir,
                       const std::string& what,
                       const std::function<void(const std::filesystem::path&)>& write);

}  // namespace hmc
