#pragma once
/// \file The element and face types a mesh is made of, their node counts and names, and the
/// fixed-size coordinate arrays of one element or face. The finite elements (fem/element.hpp)
/// name the same types as fem::ElementType, fem::FaceType.
#include <Eigen/Dense>

namespace flexopt::mesh {

/// Volume element types (isoparametric, Lagrange).
enum class ElementType { Tet4, Tet10, Hex8 };
/// Boundary face types: Tri3 (face of Tet4), Tri6 (face of Tet10), Quad4 (face of Hex8).
/// Boundary entities: surface faces (Tri3, Tri6, Quad4) and curve edges (Line2, Line3; Gmsh
/// Line3 order: end nodes 0, 1, then the mid node 2). Edges use the first reference
/// coordinate on [-1, 1]; their "area" is a length and their traction a force per length.
enum class FaceType { Tri3, Tri6, Quad4, Line2, Line3 };

/// Maximum number of nodes of a volume element (Tet10).
constexpr int kMaxNodes = 10;
/// Maximum number of nodes of a face (room for a future Quad9).
constexpr int kMaxFaceNodes = 9;

/// Number of nodes of a volume element: 4, 10, 8.
int nodes_per_element(ElementType type);
/// Number of nodes of a face: 3, 6, 4, 2, 3.
int nodes_per_face(FaceType type);
/// "Tet4", "Tet10", "Hex8".
const char *element_name(ElementType type);
/// "Tri3", "Tri6", "Quad4", "Line2", "Line3".
const char *face_name(FaceType type);
/// Number of corner (vertex) nodes: 4 for tets, 8 for hex (used by the METIS dual graph). The
/// corner nodes are always the first ones in the element's node list.
int corner_nodes(ElementType type);
/// 0, 1, 2 for Tet4, Tet10, Hex8 (tables indexed by type). Throws flexopt::Error for a value
/// outside the enum.
int type_index(ElementType type);
/// 0 ... 4 for Tri3, Tri6, Quad4, Line2, Line3.
int face_index(FaceType type);

/// Nodal coordinates of a volume element [m]: one row per node (nodes_per_element rows).
using ElementCoords = Eigen::Matrix<double, Eigen::Dynamic, 3, Eigen::RowMajor, kMaxNodes, 3>;
/// Nodal coordinates of a face [m]: one row per face node (nodes_per_face rows).
using FaceCoords = Eigen::Matrix<double, Eigen::Dynamic, 3, Eigen::RowMajor, kMaxFaceNodes, 3>;

} // namespace flexopt::mesh
