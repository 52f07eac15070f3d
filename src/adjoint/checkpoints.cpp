#include "flexopt/adjoint/checkpoints.hpp"

#include "flexopt/core/error.hpp"

#include <filesystem>
#include <hdf5.h>

namespace flexopt::adjoint {

BinomialSchedule::BinomialSchedule(long long steps, int slots)
    : steps_(steps), slots_(slots),
      cost_(static_cast<std::size_t>(slots + 1), std::vector<long long>(steps + 1, 0)),
      split_(static_cast<std::size_t>(slots + 1), std::vector<long long>(steps + 1, 0)) {
  if (steps < 0 || slots < 0) throw Error("BinomialSchedule: negative size");
  for (int c = 0; c <= slots; ++c) {
    auto &T = cost_[static_cast<std::size_t>(c)];
    auto &K = split_[static_cast<std::size_t>(c)];
    for (long long l = 1; l <= steps; ++l) {
      const auto L = static_cast<std::size_t>(l);
      if (l == 1 || c == 0) {
        T[L] = l * (l + 1) / 2;
        K[L] = l;
        continue;
      }
      const auto &Tc1 = cost_[static_cast<std::size_t>(c - 1)];
      auto f = [&](long long k) {
        return k + Tc1[static_cast<std::size_t>(l - k)] + T[static_cast<std::size_t>(k - 1)];
      };
      long long k = std::max(K[L - 1], 1LL);
      while (k + 1 <= l && f(k + 1) <= f(k)) ++k;
      T[L] = f(k);
      K[L] = k;
    }
  }
}

long long BinomialSchedule::cost(long long l, int c) const {
  return cost_[static_cast<std::size_t>(c)][static_cast<std::size_t>(l)];
}

long long BinomialSchedule::split(long long l, int c) const {
  return split_[static_cast<std::size_t>(c)][static_cast<std::size_t>(l)];
}

std::vector<long long> BinomialSchedule::first_descent() const {
  std::vector<long long> out;
  long long a = 0;
  for (int c = slots_; c > 0 && steps_ - a > 1; --c) {
    a += split(steps_ - a, c);
    out.push_back(a);
  }
  return out;
}

namespace {

class MemoryStore : public CheckpointStore {
public:
  void put(long long i, const StepRecord &r) override {
    erase(i);
    const long long b = record_bytes(r);
    records_[i] = {r, b};
    bytes_ += b;
    peak_ = std::max(peak_, bytes_);
  }
  StepRecord get(long long i) const override {
    const auto it = records_.find(i);
    if (it == records_.end()) throw Error("checkpoints: no stored state " + std::to_string(i));
    return it->second.first;
  }
  void erase(long long i) override {
    const auto it = records_.find(i);
    if (it == records_.end()) return;
    bytes_ -= it->second.second;
    records_.erase(it);
  }
  long long bytes() const override { return bytes_; }
  long long peak_bytes() const override { return peak_; }

  static long long state_bytes(const dynamics::State &s) {
    return static_cast<long long>(sizeof(double)) *
           (1 + s.q.size() + s.v.size() + s.a.size() + s.acc.size() + s.lambda.size());
  }
  static long long record_bytes(const StepRecord &r) {
    long long b = state_bytes(r.state);
    for (const auto &s : r.substeps) b += state_bytes(s.first) + 8;
    return b;
  }

private:
  std::map<long long, std::pair<StepRecord, long long>> records_;
  long long bytes_ = 0, peak_ = 0;
};

/// [n, m, t, packed state, substeps, (dt, t, packed)...] as one array of doubles.
std::vector<double> pack(const StepRecord &r) {
  const auto n = r.state.q.size(), m = r.state.lambda.size();
  std::vector<double> out{static_cast<double>(n), static_cast<double>(m)};
  auto add = [&](const dynamics::State &s) {
    out.push_back(s.t);
    const Eigen::VectorXd p = s.pack();
    out.insert(out.end(), p.data(), p.data() + p.size());
  };
  add(r.state);
  out.push_back(static_cast<double>(r.substeps.size()));
  for (const auto &[s, dt] : r.substeps) {
    out.push_back(dt);
    add(s);
  }
  return out;
}

StepRecord unpack(const std::vector<double> &d) {
  const auto n = static_cast<int>(d[0]), m = static_cast<int>(d[1]);
  const std::size_t size = static_cast<std::size_t>(4 * n + m);
  std::size_t pos = 2;
  auto take = [&]() {
    dynamics::State s;
    s.t = d[pos++];
    s.unpack(Eigen::Map<const Eigen::VectorXd>(d.data() + pos, static_cast<Eigen::Index>(size)), n,
             m);
    pos += size;
    return s;
  };
  StepRecord r;
  r.state = take();
  const auto subs = static_cast<std::size_t>(d[pos++]);
  for (std::size_t k = 0; k < subs; ++k) {
    const double dt = d[pos++];
    r.substeps.emplace_back(take(), dt);
  }
  return r;
}

class DiskStore : public CheckpointStore {
public:
  explicit DiskStore(std::string path) : path_(std::move(path)) {
    file_ = H5Fcreate(path_.c_str(), H5F_ACC_TRUNC, H5P_DEFAULT, H5P_DEFAULT);
    if (file_ < 0) throw Error("adjoint.storage: disk: cannot create the checkpoint file " + path_);
  }
  ~DiskStore() override {
    if (file_ >= 0) H5Fclose(file_);
    std::error_code ec;
    std::filesystem::remove(path_, ec);
  }
  void put(long long i, const StepRecord &r) override {
    erase(i);
    const std::vector<double> d = pack(r);
    const hsize_t dims = d.size();
    const hid_t space = H5Screate_simple(1, &dims, nullptr);
    const std::string name = "s" + std::to_string(i);
    const hid_t set = H5Dcreate2(file_, name.c_str(), H5T_NATIVE_DOUBLE, space, H5P_DEFAULT,
                                 H5P_DEFAULT, H5P_DEFAULT);
    const herr_t status =
        set < 0 ? -1 : H5Dwrite(set, H5T_NATIVE_DOUBLE, H5S_ALL, H5S_ALL, H5P_DEFAULT, d.data());
    if (set >= 0) H5Dclose(set);
    H5Sclose(space);
    if (status < 0)
      throw Error("adjoint.storage: disk: writing " + name + " to " + path_ + " failed");
    sizes_[i] = static_cast<long long>(d.size() * sizeof(double));
    bytes_ += sizes_[i];
    peak_ = std::max(peak_, bytes_);
  }
  StepRecord get(long long i) const override {
    const std::string name = "s" + std::to_string(i);
    const auto it = sizes_.find(i);
    if (it == sizes_.end()) throw Error("checkpoints: no stored state " + std::to_string(i));
    std::vector<double> d(static_cast<std::size_t>(it->second) / sizeof(double));
    const hid_t set = H5Dopen2(file_, name.c_str(), H5P_DEFAULT);
    const herr_t status =
        set < 0 ? -1 : H5Dread(set, H5T_NATIVE_DOUBLE, H5S_ALL, H5S_ALL, H5P_DEFAULT, d.data());
    if (set >= 0) H5Dclose(set);
    if (status < 0)
      throw Error("adjoint.storage: disk: reading " + name + " from " + path_ + " failed");
    return unpack(d);
  }
  void erase(long long i) override {
    const auto it = sizes_.find(i);
    if (it == sizes_.end()) return;
    H5Ldelete(file_, ("s" + std::to_string(i)).c_str(), H5P_DEFAULT);
    bytes_ -= it->second;
    sizes_.erase(it);
  }
  long long bytes() const override { return bytes_; }
  long long peak_bytes() const override { return peak_; }

private:
  std::string path_;
  hid_t file_ = -1;
  std::map<long long, long long> sizes_;
  long long bytes_ = 0, peak_ = 0;
};

} // namespace

std::unique_ptr<CheckpointStore> memory_store() {
  return std::make_unique<MemoryStore>();
}

std::unique_ptr<CheckpointStore> disk_store(const std::string &path) {
  return std::make_unique<DiskStore>(path);
}

long long reverse_binomial(const BinomialSchedule &schedule, CheckpointStore &store,
                           const std::function<StepRecord(const StepRecord &, long long)> &advance,
                           const std::function<void(long long, const StepRecord &)> &visit) {
  long long recomputed = 0;
  // State j from the stored state a (a < j).
  auto recompute = [&](long long a, long long j) {
    StepRecord r = store.get(a);
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

} // namespace flexopt::adjoint
