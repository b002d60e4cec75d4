#pragma once
#include <stdexcept>
#include <string>

namespace gcmap {

// Every user-facing failure (bad file, bad parameter) is thrown as this, with a one-line message
// that names the offending file or option; the CLI prints it and exits with code 2.
class Error : public std::runtime_error {
 public:
  using std::runtime_error::runtime_error;
};

}  // namespace gcmap
