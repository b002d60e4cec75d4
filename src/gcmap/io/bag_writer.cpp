#include "gcmap/io/bag_writer.hpp"

namespace gcmap {

namespace detail {
std::unique_ptr<BagWriter> make_mcap_writer(const std::string& path, const BagWriterOptions& o);
std::unique_ptr<BagWriter> make_ros1_writer(const std::string& path, const BagWriterOptions& o);
std::unique_ptr<BagWriter> make_db3_writer(const std::string& path, const BagWriterOptions& o);
}  // namespace detail

MessageEncoding message_encoding(BagFormat format) {
  return format == BagFormat::ros1 ? MessageEncoding::ros1 : MessageEncoding::cdr;
}

std::unique_ptr<BagWriter> open_bag_writer(const std::string& path, BagFormat format, const BagWriterOptions& options) {
  switch (format) {
    case BagFormat::mcap: return detail::make_mcap_writer(path, options);
    case BagFormat::ros1: return detail::make_ros1_writer(path, options);
    case BagFormat::db3: return detail::make_db3_writer(path, options);
  }
  return nullptr;
}

}  // namespace gcmap
