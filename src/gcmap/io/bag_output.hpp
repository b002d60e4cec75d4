#pragma once
// Internal to the bag writers: a file written under a temporary name, renamed by commit(), removed
// when destroyed uncommitted.
#include <cerrno>
#include <cstdio>
#include <cstring>
#include <fstream>
#include <string>
#include <string_view>

#include <unistd.h>

#include "gcmap/core/error.hpp"

namespace gcmap::detail {

class AtomicFile {
 public:
  explicit AtomicFile(const std::string& path) : path_(path), tmp_(path + ".tmp." + std::to_string(::getpid())) {
    out_.open(tmp_, std::ios::binary | std::ios::trunc);
    if (!out_) throw Error(path + ": cannot write (" + std::strerror(errno) + ")");
  }
  ~AtomicFile() {
    if (!committed_) {
      out_.close();
      std::remove(tmp_.c_str());
    }
  }
  void write(std::string_view bytes) {
    out_.write(bytes.data(), std::streamsize(bytes.size()));
    pos_ += bytes.size();
  }
  uint64_t pos() const { return pos_; }
  void write_at(uint64_t offset, std::string_view bytes) {
    out_.seekp(std::streamoff(offset));
    out_.write(bytes.data(), std::streamsize(bytes.size()));
    out_.seekp(std::streamoff(pos_));
  }
  void commit() {
    out_.flush();
    if (!out_) throw Error(path_ + ": write failed (disk full?)");
    out_.close();
    if (std::rename(tmp_.c_str(), path_.c_str()) != 0)
      throw Error(path_ + ": cannot rename temporary file (" + std::strerror(errno) + ")");
    committed_ = true;
  }

 private:
  std::string path_, tmp_;
  std::ofstream out_;
  uint64_t pos_ = 0;
  bool committed_ = false;
};

}  // namespace gcmap::detail
