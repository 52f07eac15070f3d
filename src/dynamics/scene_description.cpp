#include "flexopt/dynamics/scene_description.hpp"

#include "flexopt/core/error.hpp"

namespace flexopt::dynamics {

const char *model_name(BodyModel model) {
  switch (model) {
  case BodyModel::Rigid:
    return "rigid";
  case BodyModel::Ffrf:
    return "ffrf";
  case BodyModel::Acf:
    return "acf";
  case BodyModel::Auto:
    return "auto";
  }
  return "?";
}

BodyModel simulated_model(BodyModel model) {
  return model == BodyModel::Auto ? BodyModel::Rigid : model;
}

const char *joint_type_name(JointType type) {
  switch (type) {
  case JointType::Revolute:
    return "revolute";
  case JointType::Spherical:
    return "spherical";
  case JointType::Prismatic:
    return "prismatic";
  case JointType::Fixed:
    return "fixed";
  }
  return "?";
}

const char *quantity_name(SensorQuantity quantity) {
  switch (quantity) {
  case SensorQuantity::Position:
    return "position";
  case SensorQuantity::Displacement:
    return "displacement";
  case SensorQuantity::ElasticDisplacement:
    return "elastic_displacement";
  case SensorQuantity::RotationAngle:
    return "rotation_angle";
  case SensorQuantity::Reaction:
    return "reaction";
  }
  return "?";
}

const char *frame_name(reduce::FrameCondition frame) {
  return frame == reduce::FrameCondition::Chord ? "chord" : "clamped";
}

const BodyDescription &SceneDescription::body(const std::string &name) const {
  for (const BodyDescription &b : bodies)
    if (b.name == name) return b;
  throw Error("no body '" + name + "' in " + file, true);
}

} // namespace flexopt::dynamics
