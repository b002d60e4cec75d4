#include "gcmap/io/compression.hpp"

#include <bzlib.h>
#include <lz4frame.h>
#include <zstd.h>

#include <algorithm>
#include <memory>

#include "gcmap/core/error.hpp"

namespace gcmap {

namespace {

// Grows `out` geometrically (never beyond max_size) while `step` produces data; `step(dst, cap)`
// returns {bytes written, finished}.
template <typename Step>
void grow_decode(std::string& out, uint64_t max_size, uint64_t hint, const std::string& where, Step&& step) {
  // One byte of room beyond max_size tells "exactly max_size" from "more".
  const uint64_t limit = max_size + 1;
  out.clear();
  size_t used = 0;
  out.resize(size_t(std::min<uint64_t>(std::max<uint64_t>(hint, 4096), limit)));
  for (;;) {
    if (used == out.size()) {
      if (out.size() >= limit)
        throw Error(where + ": decompressed data larger than the declared " + std::to_string(max_size) + " bytes");
      out.resize(size_t(std::min<uint64_t>(uint64_t(out.size()) * 2, limit)));
    }
    const auto [written, finished] = step(out.data() + used, out.size() - used);
    used += written;
    if (finished) break;
  }
  out.resize(used);
}

void zstd_decompress(std::string_view in, uint64_t max_size, std::string& out, const std::string& where) {
  std::unique_ptr<ZSTD_DCtx, size_t (*)(ZSTD_DCtx*)> ctx(ZSTD_createDCtx(), ZSTD_freeDCtx);
  ZSTD_inBuffer src{in.data(), in.size(), 0};
  grow_decode(out, max_size, in.size() * 4, where, [&](char* dst, size_t cap) {
    ZSTD_outBuffer o{dst, cap, 0};
    const size_t r = ZSTD_decompressStream(ctx.get(), &o, &src);
    if (ZSTD_isError(r)) throw Error(where + ": corrupt zstd data (" + ZSTD_getErrorName(r) + ")");
    const bool stalled = o.pos == 0 && src.pos == src.size && o.pos < cap;
    if (stalled && r != 0) throw Error(where + ": zstd data ends early");
    return std::pair<size_t, bool>{o.pos, r == 0 && src.pos == src.size};
  });
}

void lz4_decompress(std::string_view in, uint64_t max_size, std::string& out, const std::string& where) {
  LZ4F_dctx* raw = nullptr;
  if (LZ4F_isError(LZ4F_createDecompressionContext(&raw, LZ4F_VERSION))) throw Error(where + ": lz4 init failed");
  std::unique_ptr<LZ4F_dctx, size_t (*)(LZ4F_dctx*)> ctx(raw, LZ4F_freeDecompressionContext);
  size_t in_pos = 0;
  grow_decode(out, max_size, in.size() * 4, where, [&](char* dst, size_t cap) {
    size_t dst_size = cap, src_size = in.size() - in_pos;
    const size_t r = LZ4F_decompress(ctx.get(), dst, &dst_size, in.data() + in_pos, &src_size, nullptr);
    if (LZ4F_isError(r)) throw Error(where + ": corrupt lz4 data (" + LZ4F_getErrorName(r) + ")");
    in_pos += src_size;
    if (r != 0 && in_pos == in.size() && dst_size == 0) throw Error(where + ": lz4 data ends early");
    return std::pair<size_t, bool>{dst_size, r == 0};
  });
}

void bz2_decompress(std::string_view in, uint64_t max_size, std::string& out, const std::string& where) {
  bz_stream s{};
  if (BZ2_bzDecompressInit(&s, 0, 0) != BZ_OK) throw Error(where + ": bz2 init failed");
  std::unique_ptr<bz_stream, int (*)(bz_stream*)> guard(&s, BZ2_bzDecompressEnd);
  s.next_in = const_cast<char*>(in.data());
  s.avail_in = unsigned(std::min<size_t>(in.size(), 0xFFFFFFFFu));
  grow_decode(out, max_size, in.size() * 4, where, [&](char* dst, size_t cap) {
    s.next_out = dst;
    s.avail_out = unsigned(std::min<size_t>(cap, 0x7FFFFFFFu));
    const unsigned before = s.avail_out;
    const int r = BZ2_bzDecompress(&s);
    const size_t written = before - s.avail_out;
    if (r != BZ_OK && r != BZ_STREAM_END) throw Error(where + ": corrupt bz2 data (code " + std::to_string(r) + ")");
    if (r == BZ_OK && s.avail_in == 0 && written == 0) throw Error(where + ": bz2 data ends early");
    return std::pair<size_t, bool>{written, r == BZ_STREAM_END};
  });
}

}  // namespace

void decompress(Compression c, std::string_view in, uint64_t max_size, bool exact, std::string& out, const std::string& where) {
  switch (c) {
    case Compression::none:
      if (in.size() > max_size) throw Error(where + ": data larger than the declared size");
      out.assign(in);
      break;
    case Compression::zstd: zstd_decompress(in, max_size, out, where); break;
    case Compression::lz4: lz4_decompress(in, max_size, out, where); break;
    case Compression::bz2: bz2_decompress(in, max_size, out, where); break;
  }
  if (exact && out.size() != max_size)
    throw Error(where + ": decompressed to " + std::to_string(out.size()) + " bytes, declared " + std::to_string(max_size));
}

std::string compress(Compression c, std::string_view in) {
  std::string out;
  switch (c) {
    case Compression::none: out.assign(in); break;
    case Compression::zstd: {
      out.resize(ZSTD_compressBound(in.size()));
      const size_t n = ZSTD_compress(out.data(), out.size(), in.data(), in.size(), 1);
      if (ZSTD_isError(n)) throw Error(std::string("zstd compression failed: ") + ZSTD_getErrorName(n));
      out.resize(n);
      break;
    }
    case Compression::lz4: {
      LZ4F_preferences_t prefs{};
      prefs.frameInfo.contentSize = in.size();
      out.resize(LZ4F_compressFrameBound(in.size(), &prefs));
      const size_t n = LZ4F_compressFrame(out.data(), out.size(), in.data(), in.size(), &prefs);
      if (LZ4F_isError(n)) throw Error(std::string("lz4 compression failed: ") + LZ4F_getErrorName(n));
      out.resize(n);
      break;
    }
    case Compression::bz2: {
      unsigned n = unsigned(in.size() + in.size() / 100 + 600);
      out.resize(n);
      if (BZ2_bzBuffToBuffCompress(out.data(), &n, const_cast<char*>(in.data()), unsigned(in.size()), 9, 0, 0) != BZ_OK)
        throw Error("bz2 compression failed");
      out.resize(n);
      break;
    }
  }
  return out;
}

}  // namespace gcmap
