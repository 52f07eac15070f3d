#include "flexopt/io/location.hpp"

namespace flexopt::io {

std::string Location::str() const {
  return file + ":" + std::to_string(line) + ":" + std::to_string(column);
}

} // namespace flexopt::io
