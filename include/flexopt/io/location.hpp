#pragma once
/// \file Where a key stands in case.yaml, for messages raised after the case is read (a physical
/// group the mesh lacks, a sensor outside its body): the settings of every module carry it.
#include <string>

namespace flexopt::io {

/// Position of a key in case.yaml. `str()` is "path/case.yaml:LINE:COL".
struct Location {
  std::string file;
  int line = 0;
  int column = 0;
  std::string str() const;
};

} // namespace flexopt::io
