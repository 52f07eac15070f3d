#pragma once
/// \file The design of a topology optimization: one DesignField per design body (`design:`, one
/// entry or a list), their variables concatenated into the one vector the optimizer sees
/// (docs/theory.md 9.9): on every rank the local variables of field 0, then those of field 1,
/// and so on. One field: exactly that field's vector.
#include "flexopt/io/xdmf.hpp"
#include "flexopt/optimize/design_field.hpp"

#include <array>
#include <cstdint>
#include <memory>
#include <petscvec.h>
#include <string>
#include <vector>

namespace flexopt::optimize {

class Design {
public:
  /// The fields, in the order of `design:` (at least one, all on one communicator).
  explicit Design(std::vector<std::unique_ptr<DesignField>> fields);
  ~Design();
  Design(const Design &) = delete;
  Design &operator=(const Design &) = delete;

  std::size_t size() const { return fields_.size(); }
  DesignField &field(std::size_t k) { return *fields_[k]; }
  const DesignField &field(std::size_t k) const { return *fields_[k]; }
  MPI_Comm comm() const { return fields_.front()->mesh().comm; }

  /// A vector over every field's design variables (caller destroys it). Collective.
  Vec create_design_vector() const;
  /// Each field's design.initial. Collective.
  void initial_design(Vec x) const;
  PetscInt design_size() const { return global_; }
  /// Local design variables of field k, and where they start in the local part of a design
  /// vector.
  PetscInt local_size(std::size_t k) const { return local_[k]; }
  PetscInt local_offset(std::size_t k) const { return offset_[k]; }
  /// A key per local design variable, unique over the fields and the same on any rank count:
  /// field 0's Gmsh element tags, field k's tag + k 2^48 (restart files, --design).
  const std::vector<std::uint64_t> &design_keys() const { return keys_; }
  /// A key's field and Gmsh tag, and the key of field k's tag.
  static std::size_t key_field(std::uint64_t key) { return static_cast<std::size_t>(key >> 48); }
  static long long key_tag(std::uint64_t key) {
    return static_cast<long long>(key & ((std::uint64_t{1} << 48) - 1));
  }
  static std::uint64_t key(std::size_t k, std::uint64_t tag) {
    return tag + (std::uint64_t{k} << 48);
  }

  /// Every field's update from its part of x (DesignField::update). Collective.
  void update(Vec x);
  /// Field k's pull-back of the element vector g_physical (overwritten) into its part of g_x.
  /// Collective over the fields' communicator.
  void pull_back(std::size_t k, Vec g_physical, Vec g_x);

  /// The projection's continuation (docs/theory.md 9.9): stages() = the longest
  /// design.projection.beta (0: no field is projected); at stage s field k takes
  /// beta_k[min(s, len_k - 1)].
  int stages() const;
  void set_stage(int stage);
  /// Iterations per stage (the projected fields' `every`, one value).
  int stage_length() const;
  /// The sharpness of every projected field at `stage`: "8", or "coupler 8, rocker 4".
  std::string stage_text(int stage) const;
  /// Every field's beta, and their restore (simulate and check-gradient keep a run's stage).
  std::vector<double> betas() const;
  void set_betas(const std::vector<double> &betas);

  /// The volume fraction of the design regions of `bodies` together (their volumes as weights;
  /// empty: every field's), of field k alone, and the derivative of the first with respect to
  /// field k's physical densities (element vector g; zero when k is not listed).
  double volume_fraction(const std::vector<std::string> &bodies = {}) const;
  double volume_fraction(std::size_t k) const { return fields_[k]->volume_fraction(); }
  void volume_fraction_gradient(const std::vector<std::string> &bodies, std::size_t k, Vec g) const;

  /// The filters' descriptions, each after its body's name when there are several fields.
  std::string filter_description() const;
  /// The design bodies' meshes as one grid (`placed[k]`, when given: field k's owned node
  /// coordinates in its body's placement), and an element field of every field's local elements
  /// in that grid's order (field 0's local elements, then field 1's, ...).
  io::GridLayout grid_layout(const std::vector<std::vector<double>> &placed = {}) const;
  std::vector<double> cells(Vec (DesignField::*which)() const) const;
  /// Each field's owned node coordinates placed by `placements[k]` (p, then R row-major:
  /// x = p + R X), for grid_layout.
  std::vector<std::vector<double>>
  placed_coordinates(const std::vector<std::array<double, 12>> &placements) const;
  long long global_elements() const;

private:
  std::vector<std::unique_ptr<DesignField>> fields_;
  std::vector<PetscInt> local_, offset_;
  PetscInt global_ = 0, local_total_ = 0;
  std::vector<std::uint64_t> keys_;
  std::vector<Vec> parts_; ///< per field: a vector of its layout without an array (placed)
};

} // namespace flexopt::optimize
