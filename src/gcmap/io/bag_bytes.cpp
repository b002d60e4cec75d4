#include "gcmap/io/bag_bytes.hpp"

#include <fcntl.h>
#include <sys/stat.h>
#include <unistd.h>

#include <array>
#include <cerrno>

#include "gcmap/core/error.hpp"

namespace gcmap {

std::string_view ByteReader::bytes(uint64_t n) {
  if (n > remaining())
    fail("truncated: needs " + std::to_string(n) + " bytes at offset " + std::to_string(pos_) + ", " +
         std::to_string(remaining()) + " left");
  std::string_view v = data_.substr(pos_, n);
  pos_ += n;
  return v;
}

void ByteReader::fail(const std::string& what) const { throw Error(where_ + ": " + what); }

void ByteSource::check_range(uint64_t offset, uint64_t n) const {
  if (offset > size_ || n > size_ - offset)
    throw Error(name_ + ": truncated: needs bytes [" + std::to_string(offset) + ", " + std::to_string(offset + n) + ") of a " +
                std::to_string(size_) + "-byte file");
}

namespace {

class FileSource : public ByteSource {
 public:
  explicit FileSource(const std::string& path) {
    name_ = path;
    fd_ = ::open(path.c_str(), O_RDONLY | O_CLOEXEC);
    if (fd_ < 0) throw Error(path + ": cannot open (" + std::strerror(errno) + ")");
    struct stat st {};
    if (::fstat(fd_, &st) != 0 || !S_ISREG(st.st_mode)) {
      ::close(fd_);
      throw Error(path + ": not a regular file");
    }
    size_ = uint64_t(st.st_size);
  }
  ~FileSource() override { ::close(fd_); }

  void read(uint64_t offset, uint64_t n, std::string& out) const override {
    check_range(offset, n);
    out.resize(n);
    uint64_t done = 0;
    while (done < n) {
      const ssize_t r = ::pread(fd_, out.data() + done, n - done, off_t(offset + done));
      if (r < 0 && errno == EINTR) continue;
      if (r <= 0) throw Error(name_ + ": read error at offset " + std::to_string(offset + done));
      done += uint64_t(r);
    }
  }

 private:
  int fd_ = -1;
};

class MemorySource : public ByteSource {
 public:
  MemorySource(std::string bytes, const std::string& name) : bytes_(std::move(bytes)) {
    name_ = name;
    size_ = bytes_.size();
  }
  void read(uint64_t offset, uint64_t n, std::string& out) const override {
    check_range(offset, n);
    out.assign(bytes_, offset, n);
  }

 private:
  std::string bytes_;
};

// Slicing-by-8 tables: 8 bytes per step, several times faster than the byte-wise loop.
std::array<std::array<uint32_t, 256>, 8> make_crc_tables() {
  std::array<std::array<uint32_t, 256>, 8> t{};
  for (uint32_t i = 0; i < 256; ++i) {
    uint32_t c = i;
    for (int k = 0; k < 8; ++k) c = (c & 1) ? 0xEDB88320u ^ (c >> 1) : c >> 1;
    t[0][i] = c;
  }
  for (uint32_t i = 0; i < 256; ++i)
    for (int s = 1; s < 8; ++s) t[s][i] = (t[s - 1][i] >> 8) ^ t[0][t[s - 1][i] & 0xFF];
  return t;
}

}  // namespace

std::unique_ptr<ByteSource> open_file_source(const std::string& path) { return std::make_unique<FileSource>(path); }

std::unique_ptr<ByteSource> memory_source(std::string bytes, const std::string& name) {
  return std::make_unique<MemorySource>(std::move(bytes), name);
}

uint32_t crc32(std::string_view data, uint32_t crc) {
  static const auto t = make_crc_tables();
  crc = ~crc;
  const auto* p = reinterpret_cast<const uint8_t*>(data.data());
  size_t n = data.size();
  while (n >= 8) {
    uint32_t lo, hi;
    std::memcpy(&lo, p, 4);
    std::memcpy(&hi, p + 4, 4);
    lo ^= crc;
    crc = t[7][lo & 0xFF] ^ t[6][(lo >> 8) & 0xFF] ^ t[5][(lo >> 16) & 0xFF] ^ t[4][lo >> 24] ^ t[3][hi & 0xFF] ^
          t[2][(hi >> 8) & 0xFF] ^ t[1][(hi >> 16) & 0xFF] ^ t[0][hi >> 24];
    p += 8;
    n -= 8;
  }
  while (n--) crc = t[0][(crc ^ *p++) & 0xFF] ^ (crc >> 8);
  return ~crc;
}

}  // namespace gcmap
