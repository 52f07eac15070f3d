#include "flexopt/mesh/element_type.hpp"

#include "flexopt/core/error.hpp"

#include <string>

namespace flexopt::mesh {

int type_index(ElementType type) {
  switch (type) {
  case ElementType::Tet4:
    return 0;
  case ElementType::Tet10:
    return 1;
  case ElementType::Hex8:
    return 2;
  }
  throw Error("flexopt::fem: invalid ElementType value " + std::to_string(static_cast<int>(type)));
}

int face_index(FaceType type) {
  switch (type) {
  case FaceType::Tri3:
    return 0;
  case FaceType::Tri6:
    return 1;
  case FaceType::Quad4:
    return 2;
  case FaceType::Line2:
    return 3;
  case FaceType::Line3:
    return 4;
  }
  throw Error("flexopt::fem: invalid FaceType value " + std::to_string(static_cast<int>(type)));
}

int nodes_per_element(ElementType type) {
  static constexpr int kNodes[3] = {4, 10, 8};
  return kNodes[type_index(type)];
}

int nodes_per_face(FaceType type) {
  static constexpr int kNodes[5] = {3, 6, 4, 2, 3};
  return kNodes[face_index(type)];
}

const char *element_name(ElementType type) {
  static constexpr const char *kNames[3] = {"Tet4", "Tet10", "Hex8"};
  return kNames[type_index(type)];
}

const char *face_name(FaceType type) {
  static constexpr const char *kNames[5] = {"Tri3", "Tri6", "Quad4", "Line2", "Line3"};
  return kNames[face_index(type)];
}

int corner_nodes(ElementType type) {
  static constexpr int kCorners[3] = {4, 4, 8};
  return kCorners[type_index(type)];
}

} // namespace flexopt::mesh
