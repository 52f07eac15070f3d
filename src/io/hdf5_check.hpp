#pragma once
/// \file Checks of HDF5 return values for the io module's writers (private to src/io).
///
/// Every HDF5 call after a file exists is part of a collective sequence; a failure may be seen
/// by one rank only, so it ends the job (abort_local) instead of throwing: unwinding would run
/// collective destructors (closing the file) while the other ranks wait elsewhere.
#include "flexopt/core/error.hpp"

#include <hdf5.h>
#include <string>

namespace flexopt::io::detail {

inline void h5check(herr_t status, const std::string &what) {
  if (status < 0) abort_local("HDF5: " + what + " failed");
}

inline hid_t h5id(hid_t id, const std::string &what) {
  if (id < 0) abort_local("HDF5: " + what + " failed");
  return id;
}

} // namespace flexopt::io::detail
