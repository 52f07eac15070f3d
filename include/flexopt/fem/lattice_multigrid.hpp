#pragma once
/// \file Geometric multigrid for Hex8 meshes that are a structured lattice (Gmsh's transfinite
/// boxes): every node is a point (x_i, y_j, z_k) of a tensor grid and every element spans one
/// cell of it. A coarse level keeps every second lattice line of the next finer one, its
/// interpolation is trilinear in the lattice coordinates (exact for the Hex8 field of the coarse
/// cells), and its operator is the Galerkin product P^T A P (PCMG). docs/theory.md section 1,
/// "Geometric multigrid on a structured Hex8 lattice".
#include "flexopt/mesh/distributed_mesh.hpp"

#include <array>
#include <optional>
#include <petscksp.h>
#include <string>
#include <vector>

namespace flexopt::fem {

struct Lattice {
  /// Coordinates of the lattice lines along x, y, z (ascending).
  std::array<std::vector<double>, 3> axis;
  /// Global node number of lattice point (i, j, k) at i + n_x (j + n_y k), n_a = axis[a].size().
  std::vector<PetscInt> node;
  PetscInt points(int a) const {
    return static_cast<PetscInt>(axis[static_cast<std::size_t>(a)].size());
  }
  PetscInt cells(int a) const { return points(a) - 1; }
};

/// The lattice of a Hex8 mesh, or nothing: another element type, a node off the tensor grid of
/// the node coordinates (to 1e-9 of the bounding box), or an element not spanning exactly one
/// cell. Collective; the same answer on every rank.
std::optional<Lattice> find_lattice(const mesh::DistributedMesh &mesh);

/// The levels of a lattice hierarchy: cells per axis, finest first. Coarsens while every cell
/// count is even and, with `levels` = 0, at least twice (a coarsest spacing of 4 cells: coarser
/// ones lose the thin members of a SIMP design, docs/solvers.md) and then while the level has
/// more than `coarse_dofs` DOFs (3 per node); with `levels` > 0, until there are that many (or
/// no even split is left).
std::vector<std::array<PetscInt, 3>> lattice_levels(const Lattice &lattice, int levels,
                                                    PetscInt coarse_dofs);

/// Makes `pc` a Galerkin geometric multigrid (PCMG, V-cycle) on the lattice with the given
/// levels (lattice_levels; at least 2); the interpolations are 3-component (block size 3)
/// trilinear maps. Smoothers and the coarse solver are left to PCMG's defaults and the options
/// (-mg_levels_*, -mg_coarse_*). Returns a one-line description. Collective.
std::string set_lattice_multigrid(PC pc, const mesh::DistributedMesh &mesh, const Lattice &lattice,
                                  const std::vector<std::array<PetscInt, 3>> &levels);

/// The coarse operators of a lattice multigrid (set_lattice_multigrid) whose finest operator is
/// applied without its matrix (MatrixFreeStiffness as the KSP's Amat, the assembled stiffness as
/// its Pmat). PCMG forms Galerkin products from the Amat too, which a shell matrix cannot give;
/// here the finest level smooths and forms residuals with the Amat (PCSetUseAmat) and the coarse
/// operators are P^T A P of the assembled Pmat, level by level, the same MatPtAP products PCMG
/// forms. Call update() after every change of the Pmat's values. Collective.
class LatticeCoarseOperators {
public:
  explicit LatticeCoarseOperators(PC pc);
  ~LatticeCoarseOperators();
  LatticeCoarseOperators(const LatticeCoarseOperators &) = delete;
  LatticeCoarseOperators &operator=(const LatticeCoarseOperators &) = delete;
  /// Forms every coarse operator from `fine` (the assembled finest operator) and gives it to its
  /// level (the first time; later the same matrices get new values).
  void update(Mat fine);

private:
  PC pc_;
  std::vector<Mat> coarse_; ///< PCMG level l's operator at [l] (0: coarsest)
};

} // namespace flexopt::fem
