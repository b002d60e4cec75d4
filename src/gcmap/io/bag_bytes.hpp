#pragma once
// Bounds-checked little-endian reading and writing for the bag containers. Every length read from a
// file is checked against the bytes that remain before anything is allocated from it.
#include <cstdint>
#include <cstring>
#include <memory>
#include <string>
#include <string_view>
#include <utility>

namespace gcmap {

// Reads fields from a byte span; any read past the end throws Error("<where>: truncated ...").
class ByteReader {
 public:
  ByteReader(std::string_view data, std::string where) : data_(data), where_(std::move(where)) {}

  size_t pos() const { return pos_; }
  size_t remaining() const { return data_.size() - pos_; }
  bool done() const { return pos_ == data_.size(); }

  uint8_t u8() { return get<uint8_t>(); }
  uint16_t u16() { return get<uint16_t>(); }
  uint32_t u32() { return get<uint32_t>(); }
  uint64_t u64() { return get<uint64_t>(); }
  std::string_view bytes(uint64_t n);
  std::string_view str32() { return bytes(u32()); }  // u32 length, then the bytes
  void skip(uint64_t n) { bytes(n); }
  [[noreturn]] void fail(const std::string& what) const;

 private:
  template <typename T>
  T get() {
    T v;
    std::memcpy(&v, bytes(sizeof(T)).data(), sizeof(T));
    return v;
  }
  std::string_view data_;
  std::string where_;  // owned: callers often pass a temporary
  size_t pos_ = 0;
};

template <typename T>
T byteswap(T v) {
  char b[sizeof(T)];
  std::memcpy(b, &v, sizeof(T));
  for (size_t i = 0; i < sizeof(T) / 2; ++i) std::swap(b[i], b[sizeof(T) - 1 - i]);
  std::memcpy(&v, b, sizeof(T));
  return v;
}

// Little-endian appends for the writers.
inline void put_u8(std::string& out, uint8_t v) { out.push_back(char(v)); }
template <typename T>
void put_le(std::string& out, T v) {
  out.append(reinterpret_cast<const char*>(&v), sizeof(T));
}
inline void put_str32(std::string& out, std::string_view s) {
  put_le<uint32_t>(out, uint32_t(s.size()));
  out.append(s);
}

// Random access to a bag's bytes: a file (read with pread, nothing kept in memory) or a buffer
// (tests, fuzzing). Reads past the end throw Error("NAME: truncated ...").
class ByteSource {
 public:
  virtual ~ByteSource() = default;
  const std::string& name() const { return name_; }
  uint64_t size() const { return size_; }
  // Replaces `out` with bytes [offset, offset + n).
  virtual void read(uint64_t offset, uint64_t n, std::string& out) const = 0;

 protected:
  void check_range(uint64_t offset, uint64_t n) const;
  std::string name_;
  uint64_t size_ = 0;
};

std::unique_ptr<ByteSource> open_file_source(const std::string& path);
std::unique_ptr<ByteSource> memory_source(std::string bytes, const std::string& name);

// CRC-32 (IEEE, as MCAP uses), continued from `crc` (0 for a new one).
uint32_t crc32(std::string_view data, uint32_t crc = 0);

}  // namespace gcmap
