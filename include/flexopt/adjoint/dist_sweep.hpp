#pragma once
/// \file The backward step of the discrete adjoint on the distributed backend (docs/theory.md
/// section 9.7): the transposed solve with the scaled Newton matrix of DistributedAlpha, the
/// back-substitution with C^T mu from the element loop and the small part, and the coupling to
/// the previous state. The multipliers of a step live in the integrator's layout, one DistState per
/// response (q, v, a, acc on the coordinate entries, lambda on the multipliers; t unused).
#include "flexopt/dynamics/distributed_alpha.hpp"

#include <vector>

namespace flexopt::adjoint {

class DistBackwardSweep {
public:
  DistBackwardSweep(const dynamics::DistributedAlpha &da, int responses);
  ~DistBackwardSweep();
  DistBackwardSweep(const DistBackwardSweep &) = delete;
  DistBackwardSweep &operator=(const DistBackwardSweep &) = delete;

  /// The multipliers mu (one per response) of the step of size h that ended in `state`, with
  /// dpsi[r] = (dPsi_r/ds)^T at that state (null or an empty vector: zero). Valid until the next
  /// call. Collective.
  const std::vector<dynamics::DistState> &
  step(const dynamics::DistState &state, double h,
       const std::vector<const dynamics::DistState *> &dpsi);
  /// mu_0 = -(dPsi/ds_0)^T - (dR_1/ds_0)^T mu_1 at the initial state (dpsi0 as in step).
  /// Collective.
  std::vector<dynamics::DistState>
  finish(const std::vector<const dynamics::DistState *> &dpsi0) const;
  long long steps() const { return steps_; }

private:
  /// f = -dpsi - carry, blockwise.
  void right_hand_side(std::size_t r, const dynamics::DistState *dpsi,
                       dynamics::DistState &f) const;

  const dynamics::DistributedAlpha &da_;
  std::vector<dynamics::DistState> carry_, mu_;
  dynamics::DistState f_;
  Vec cmask_ = nullptr, lmask_ = nullptr, rhs_ = nullptr, w1_ = nullptr, w2_ = nullptr,
      w3_ = nullptr;
  std::vector<Vec> z_;
  long long steps_ = 0;
};

} // namespace flexopt::adjoint
