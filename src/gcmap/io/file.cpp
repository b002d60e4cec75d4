#include "gcmap/io/file.hpp"

#include <fcntl.h>
#include <unistd.h>

#include <cerrno>
#include <cstdio>
#include <cstring>
#include <filesystem>
#include <fstream>
#include <sstream>

#include "gcmap/core/error.hpp"

namespace gcmap {

std::string read_file(const std::string& path) {
  std::error_code ec;
  if (!std::filesystem::exists(path, ec)) throw Error(path + ": no such file");
  if (std::filesystem::is_directory(path, ec)) throw Error(path + ": is a directory, expected a file");
  std::ifstream in(path, std::ios::binary | std::ios::ate);
  if (!in) throw Error(path + ": cannot open (" + std::strerror(errno) + ")");
  // One read into a buffer of the file's size; files without one (pipes, /proc) through the stream.
  const std::streamoff size = in.tellg();
  in.seekg(0);
  if (size <= 0) {
    std::ostringstream ss;
    ss << in.rdbuf();
    if (in.bad()) throw Error(path + ": read error");
    return std::move(ss).str();
  }
  std::string bytes(static_cast<size_t>(size), '\0');
  in.read(bytes.data(), size);
  if (in.gcount() != size) throw Error(path + ": read error (file shrank while read?)");
  return bytes;
}

void write_file_atomic(const std::string& path, const std::function<void(std::ostream&)>& write) {
  const std::string tmp = path + ".tmp." + std::to_string(::getpid());
  {
    std::ofstream out(tmp, std::ios::binary | std::ios::trunc);
    if (!out) throw Error(path + ": cannot write (" + std::strerror(errno) + ")");
    try {
      write(out);
    } catch (...) {
      out.close();
      std::remove(tmp.c_str());
      throw;
    }
    out.flush();
    int why = errno;
    if (out) {
      out.close();
      why = errno;
    }
    if (!out) {
      std::remove(tmp.c_str());
      throw Error(path + ": write failed (" + std::strerror(why) + ")");
    }
  }
  if (std::rename(tmp.c_str(), path.c_str()) != 0) {
    const std::string why = std::strerror(errno);
    std::remove(tmp.c_str());
    throw Error(path + ": cannot rename temporary file (" + why + ")");
  }
}

namespace fs = std::filesystem;

void replace_folder(const std::string& from, const std::string& to) {
  std::error_code ec;
  if (!fs::exists(to)) {
    fs::rename(from, to);
    return;
  }
  if (::renameat2(AT_FDCWD, from.c_str(), AT_FDCWD, to.c_str(), RENAME_EXCHANGE) == 0) {
    fs::remove_all(from, ec);  // now the old folder
    return;
  }
  const std::string old = to + ".old." + std::to_string(::getpid());
  fs::rename(to, old);
  fs::rename(from, to);
  fs::remove_all(old, ec);
}

namespace {

// Moves every entry of `staging` over its namesake in `dir`.
void move_entries(const fs::path& staging, const fs::path& dir) {
  for (const auto& entry : fs::directory_iterator(staging)) {
    const fs::path target = dir / entry.path().filename();
    if (entry.is_directory()) replace_folder(entry.path().string(), target.string());
    else fs::rename(entry.path(), target);
  }
}

}  // namespace

void write_folder_contents_atomic(const std::string& dir, const std::function<void(const std::string&)>& write) {
  const fs::path staging = fs::path(dir) / (".incomplete." + std::to_string(::getpid()));
  std::error_code ec;
  fs::remove_all(staging, ec);
  if (!fs::create_directories(staging, ec) || ec) throw Error(staging.string() + ": cannot create (" + ec.message() + ")");
  try {
    write(staging.string());
    move_entries(staging, dir);
  } catch (const Error& e) {
    fs::remove_all(staging, ec);
    std::string what = e.what();
    for (size_t at; (at = what.find(staging.string())) != std::string::npos;) what.replace(at, staging.string().size(), dir);
    throw Error(what + "; the previous outputs in " + dir + " are unchanged");
  } catch (const fs::filesystem_error& e) {
    fs::remove_all(staging, ec);
    throw Error(dir + ": cannot move the new outputs in (" + e.code().message() + ")");
  }
  fs::remove_all(staging, ec);
}

}  // namespace gcmap
