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

} // namespace flexopt::optimize
