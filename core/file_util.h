// Atomic file writes: every output is written to a temporary file in the
// target's folder and renamed into place, so a failed or interrupted write
// never leaves a half-written file and never destroys the previous one.
#pragma once

#include <filesystem>
#include <functional>
#include <iosfwd>
#include <string>
#include <string_view>

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

}  // namespace hmc
