#pragma once
#include <functional>
#include <ostream>
#include <string>

namespace gcmap {

// Whole file as bytes; throws Error("PATH: ...") when missing or unreadable.
std::string read_file(const std::string& path);

// Writes through a temporary file in the same folder and renames it over `path`, so readers never
// see a half-written file. Throws Error("PATH: ...") on failure and removes the temporary.
void write_file_atomic(const std::string& path, const std::function<void(std::ostream&)>& write);

// Moves the folder `from` to `to`, replacing a folder already there: one atomic exchange where the
// file system can (Linux renameat2), so there is no instant without `to`; else two renames. The old
// folder is removed. Throws std::filesystem::filesystem_error.
void replace_folder(const std::string& from, const std::string& to);

// Writes a set of outputs into a staging folder inside `dir` and moves them into `dir` only once all
// of them were written, so a full disk or a failing writer leaves the previous set whole (files and
// folders alike). `write` gets the staging folder; errors name the output's final path.
void write_folder_contents_atomic(const std::string& dir, const std::function<void(const std::string& staging)>& write);

}  // namespace gcmap
