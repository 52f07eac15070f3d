#pragma once
/// \file Checkpointing of the forward states for the backward sweep (docs/theory.md section 9.4):
/// the binomial reversal schedule (optimal for a given number of stored states) and the store
/// that holds them, in memory or in an HDF5 file.
#include "flexopt/dynamics/distributed_alpha.hpp"
#include "flexopt/dynamics/generalized_alpha.hpp"
#include "flexopt/dynamics/integrator.hpp"

#include <functional>
#include <map>
#include <memory>
#include <string>
#include <utility>
#include <vector>

namespace flexopt::adjoint {

/// The reversal of l steps from a stored start state with c more storage slots, by the
/// recursion of section 9.4: advance k steps and store that state, reverse the l - k steps
/// after it with c - 1 slots, visit it, then reverse the k - 1 steps before it with c slots;
/// with c = 0, every state is recomputed from the start. cost(l, c) is the least number of
/// steps that visits all l states in reverse order (each visit needs its state), and split(l,
/// c) the k that achieves it (computed once for all l <= steps, c <= slots by dynamic
/// programming; the optimal k is non-decreasing in l, which makes that O(steps x slots)).
class BinomialSchedule {
public:
  BinomialSchedule(long long steps, int slots);
  long long cost(long long l, int c) const;
  long long split(long long l, int c) const;
  long long steps() const { return steps_; }
  int slots() const { return slots_; }
  /// Steps of the reversal of all steps that the forward run has not made already: the
  /// forward run stores the states of the recursion's first descent (first_descent()) and
  /// ends at the last state, so cost(steps, slots) - steps remain.
  long long recomputed() const { return cost(steps_, slots_) - steps_; }
  /// The states (step indices) stored on the recursion's first descent, in increasing order.
  std::vector<long long> first_descent() const;

private:
  long long steps_;
  int slots_;
  std::vector<std::vector<long long>> cost_, split_; ///< [c][l]
};

/// One main step's end state and its substeps (dynamics::Record): on the dense backend
/// (StepRecord) and on the distributed one (DistRecord).
template <class State> using Record = dynamics::Record<State>;
using StepRecord = Record<dynamics::State>;
using DistRecord = Record<dynamics::DistState>;

/// Where the checkpointed states live. Not collective: each rank stores its replicated copy
/// (dense) or its part (distributed); bytes are this rank's.
template <class R> class Store {
public:
  virtual ~Store() = default;
  virtual void put(long long index, const R &record) = 0;
  virtual R get(long long index) const = 0;
  virtual void erase(long long index) = 0;
  /// Bytes of the states held now and at most so far.
  virtual long long bytes() const = 0;
  virtual long long peak_bytes() const = 0;
};
using CheckpointStore = Store<StepRecord>;
using DistCheckpointStore = Store<DistRecord>;

/// `storage: memory`.
std::unique_ptr<CheckpointStore> memory_store();
std::unique_ptr<DistCheckpointStore> dist_memory_store();
/// `storage: disk`: an HDF5 file `path` (this rank's; created, removed with the store). Throws a
/// flexopt::Error naming the file if it cannot be created. The distributed store creates the
/// vectors it returns in the layout of `da`.
std::unique_ptr<CheckpointStore> disk_store(const std::string &path);
std::unique_ptr<DistCheckpointStore> dist_disk_store(const std::string &path,
                                                     const dynamics::DistributedAlpha &da);

/// Runs the backward sweep over main steps N ... 1 with the states from the store and the
/// schedule: `advance(record, j)` recomputes main step j from the record of step j - 1,
/// `visit(j, record)` runs the backward steps of main step j. The store holds the records of the
/// first descent and of step 0 and N, as the forward run left them. Returns the number of
/// recomputed main steps.
template <class R>
long long reverse_binomial(const BinomialSchedule &schedule, Store<R> &store,
                           const std::function<R(const R &, long long)> &advance,
                           const std::function<void(long long, const R &)> &visit) {
  long long recomputed = 0;
  // State j from the stored state a (a < j).
  auto recompute = [&](long long a, long long j) {
    R r = store.get(a);
    for (long long i = a + 1; i <= j; ++i) {
      r = advance(r, i);
      ++recomputed;
    }
    return r;
  };
  // Visits b, b - 1, ..., a + 1 with the state a stored and c more slots; on the first descent
  // the forward run stored the split states and the last one.
  std::function<void(long long, long long, int, bool)> reverse = [&](long long a, long long b,
                                                                     int c, bool descent) {
    if (b <= a) return;
    if (c == 0 || b - a == 1) {
      for (long long j = b; j > a; --j) {
        if (descent && j == b) {
          visit(j, store.get(j));
          store.erase(j);
        } else {
          visit(j, recompute(a, j));
        }
      }
      return;
    }
    const long long m = a + schedule.split(b - a, c);
    if (!descent) store.put(m, recompute(a, m));
    reverse(m, b, c - 1, descent);
    visit(m, store.get(m));
    store.erase(m);
    reverse(a, m - 1, c, false);
  };
  reverse(0, schedule.steps(), schedule.slots(), true);
  return recomputed;
}

/// The backward sweep over main steps N ... 1: with a schedule, reverse_binomial; without one
/// (every record stored), each record visited and freed in turn. Returns the recomputed steps.
template <class R>
long long reverse_steps(const BinomialSchedule *schedule, Store<R> &store, long long steps,
                        const std::function<R(const R &, long long)> &advance,
                        const std::function<void(long long, const R &)> &visit) {
  if (schedule) return reverse_binomial<R>(*schedule, store, advance, visit);
  for (long long j = steps; j >= 1; --j) {
    visit(j, store.get(j));
    store.erase(j);
  }
  return 0;
}

} // namespace flexopt::adjoint
