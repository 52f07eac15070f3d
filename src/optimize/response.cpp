#include "flexopt/optimize/response.hpp"

namespace flexopt::optimize {

const char *response_type_name(ResponseType type) {
  switch (type) {
  case ResponseType::Compliance:
    return "compliance";
  case ResponseType::VolumeFraction:
    return "volume_fraction";
  case ResponseType::Displacement:
    return "displacement";
  case ResponseType::StrainEnergyIntegral:
    return "strain_energy_integral";
  case ResponseType::TrackingError:
    return "tracking_error";
  case ResponseType::Sensor:
    return "sensor";
  case ResponseType::Mass:
    return "mass";
  case ResponseType::Stress:
    return "stress";
  }
  return "?";
}

const char *combine_name(Combine combine) {
  switch (combine) {
  case Combine::Sum:
    return "sum";
  case Combine::Weighted:
    return "weighted";
  case Combine::Max:
    return "max";
  }
  return "?";
}

} // namespace flexopt::optimize
