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
// Throws InputError naming `path` when the file cannot be written.
void WriteFileAtomic(const std::filesystem::path& path,
                     const std::function<void(std::ostream&)>& write,
                     bool binary = false);
void WriteFileAtomic(const std::filesystem::path& path,
                     std::string_view contents);

// Reads a whole file; throws InputError naming `path` if it cannot.
std::string ReadFile(const std::filesystem::path& path);

// Creates `dir` (and parents); throws InputError if it cannot.
void EnsureDirectory(const std::filesystem::path& dir);

}  // namespace hmc
