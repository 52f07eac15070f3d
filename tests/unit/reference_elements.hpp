#pragma once
// Shared by the element tests: the reference elements' node coordinates.
#include "flexopt/fem/element.hpp"

namespace test_support {

/// Reference node coordinates in Gmsh ordering, typed from the Gmsh documentation.
inline flexopt::fem::ElementCoords reference_nodes(flexopt::fem::ElementType type) {
  flexopt::fem::ElementCoords X(flexopt::fem::nodes_per_element(type), 3);
  switch (type) {
  case flexopt::fem::ElementType::Tet4:
    X << 0, 0, 0, 1, 0, 0, 0, 1, 0, 0, 0, 1;
    break;
  case flexopt::fem::ElementType::Tet10:
    X << 0, 0, 0, 1, 0, 0, 0, 1, 0, 0, 0, 1, // corners
        0.5, 0, 0, 0.5, 0.5, 0, 0, 0.5, 0,   // edges (0,1), (1,2), (2,0)
        0, 0, 0.5, 0, 0.5, 0.5, 0.5, 0, 0.5; // edges (3,0), (3,2), (3,1)
    break;
  case flexopt::fem::ElementType::Hex8:
    X << -1, -1, -1, 1, -1, -1, 1, 1, -1, -1, 1, -1, -1, -1, 1, 1, -1, 1, 1, 1, 1, -1, 1, 1;
    break;
  }
  return X;
}

} // namespace test_support
