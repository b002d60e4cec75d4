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

}  // namespace gcmap
