#pragma once
/// \file The responses a design problem evaluates, as objective or constraint (`objective:`,
/// `constraints:`; docs/case-format.md): what each names and bounds. Static: compliance,
/// volume_fraction, displacement (docs/theory.md section 5). Dynamic (section 9.3):
/// strain_energy_integral, tracking_error, sensor, volume_fraction, mass. Both: stress (section
/// 5.1).
#include "flexopt/io/location.hpp"
#include "flexopt/optimize/stress_aggregate.hpp"

#include <array>
#include <string>
#include <vector>

namespace flexopt::optimize {

enum class ResponseType {
  Compliance,
  VolumeFraction,
  Displacement,
  StrainEnergyIntegral,
  TrackingError,
  Sensor,
  Mass,
  Stress
};
/// The case-file name: "compliance", "volume_fraction", ...
const char *response_type_name(ResponseType type);

/// How a response combines its values over the scenarios (or load cases) it names
/// (docs/theory.md section 13): their sum, a weighted sum, or their maximum as a KS aggregate.
enum class Combine { Sum, Weighted, Max };
/// "sum", "weighted", "max".
const char *combine_name(Combine combine);

/// How a `sensor` response reduces its samples over the run (section 9.3).
enum class SensorMeasure { Final, MeanSquare, KsMax };

struct ResponseSettings {
  ResponseType type = ResponseType::Compliance;
  std::string sensor;                       ///< displacement, tracking_error, sensor: a sensor name
  std::array<double, 3> direction{0, 0, 0}; ///< displacement: unit direction
  /// displacement (static): the sensor's point in body coordinates [m], and where it is given
  std::array<double, 3> point{0, 0, 0};
  io::Location point_where;
  std::string body; ///< stress: a body name; strain_energy_integral, mass: the one body named
  /// strain_energy_integral, mass: the bodies summed (one or a list, `body`); volume_fraction:
  /// the design bodies whose regions it takes together (empty: every design body)
  std::vector<std::string> bodies;
  /// tracking_error: the target position, each component a number or an expression in t
  /// (compiled when read, so flexopt::Expression(target[k]) does not throw).
  std::array<std::string, 3> target;
  int component = 0;                            ///< sensor: 0, 1, 2 (x, y, z)
  SensorMeasure measure = SensorMeasure::Final; ///< sensor
  double ks = 50; ///< sensor ks_max: the aggregation parameter k [1/unit of the sensor]
  /// stress: the aggregate (pnorm or ks, its parameter; ks: the reference stress, a constraint's
  /// max unless given), whether its scale follows the true peak (normalization: adaptive), and
  /// the physical volume whose elements it takes (empty: the whole body).
  StressAggregateSettings aggregate;
  bool adaptive = false;
  std::string region;
  /// A case with scenarios (or load cases): the ones this response takes (indices into the
  /// case's list, in its order; every one unless `scenarios:` names some), how it combines
  /// them, the weights of `weighted` (one per taken scenario) and the KS parameter of `max`
  /// (relative to the largest |value| at the first design: docs/theory.md 13.2).
  std::vector<std::size_t> scenarios;
  Combine combine = Combine::Sum;
  std::vector<double> weights;
  double combine_ks = 50;
  double max = 0; ///< constraints: upper bound
  bool has_max = false;
  io::Location where;
};

} // namespace flexopt::optimize
