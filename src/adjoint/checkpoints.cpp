#include "flexopt/adjoint/checkpoints.hpp"

#include "flexopt/core/error.hpp"

#include <algorithm>
#include <filesystem>
#include <functional>
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

long long state_bytes(const dynamics::State &s) {
  return static_cast<long long>(sizeof(double)) *
         (1 + s.q.size() + s.v.size() + s.a.size() + s.acc.size() + s.lambda.size());
}

long long state_bytes(const dynamics::DistState &s) {
  PetscInt n = 0;
  FX_PETSC(VecGetLocalSize(s.q, &n));
  return static_cast<long long>(sizeof(double)) * (1 + 5LL * n);
}

template <class R> long long record_bytes(const R &r) {
  long long b = state_bytes(r.state);
  for (const auto &s : r.substeps) b += state_bytes(s.first) + 8;
  return b;
}

template <class R> class MemoryStore : public Store<R> {
public:
  void put(long long i, const R &r) override {
    erase(i);
    const long long b = record_bytes(r);
    records_[i] = {r, b};
    bytes_ += b;
    peak_ = std::max(peak_, bytes_);
  }
  R get(long long i) const override {
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

private:
  std::map<long long, std::pair<R, long long>> records_;
  long long bytes_ = 0, peak_ = 0;
};

/// A record from its doubles at d[pos]: the end state (by `take`, which reads one state and
/// advances pos), the number of substeps, then (dt, state) per substep.
template <class R, class Take>
R unpack_record(const std::vector<double> &d, std::size_t &pos, Take &&take) {
  R r;
  r.state = take();
  const auto subs = static_cast<std::size_t>(d[pos++]);
  for (std::size_t k = 0; k < subs; ++k) {
    const double dt = d[pos++];
    r.substeps.emplace_back(take(), dt);
  }
  return r;
}

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
  return unpack_record<StepRecord>(d, pos, take);
}

/// A record's doubles and back.
template <class R> struct Codec {
  std::function<std::vector<double>(const R &)> pack;
  std::function<R(const std::vector<double> &)> unpack;
};

template <class R> class DiskStore : public Store<R> {
public:
  DiskStore(std::string path, Codec<R> codec) : path_(std::move(path)), codec_(std::move(codec)) {
    file_ = H5Fcreate(path_.c_str(), H5F_ACC_TRUNC, H5P_DEFAULT, H5P_DEFAULT);
    if (file_ < 0) throw Error("adjoint.storage: disk: cannot create the checkpoint file " + path_);
  }
  ~DiskStore() override {
    if (file_ >= 0) H5Fclose(file_);
    std::error_code ec;
    std::filesystem::remove(path_, ec);
  }
  void put(long long i, const R &r) override {
    erase(i);
    const std::vector<double> d = codec_.pack(r);
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
  R get(long long i) const override {
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
    return codec_.unpack(d);
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
  Codec<R> codec_;
  hid_t file_ = -1;
  std::map<long long, long long> sizes_;
  long long bytes_ = 0, peak_ = 0;
};

} // namespace

std::unique_ptr<CheckpointStore> memory_store() {
  return std::make_unique<MemoryStore<StepRecord>>();
}

std::unique_ptr<DistCheckpointStore> dist_memory_store() {
  return std::make_unique<MemoryStore<DistRecord>>();
}

std::unique_ptr<CheckpointStore> disk_store(const std::string &path) {
  return std::make_unique<DiskStore<StepRecord>>(path, Codec<StepRecord>{pack, unpack});
}

std::unique_ptr<DistCheckpointStore> dist_disk_store(const std::string &path,
                                                     const dynamics::DistributedAlpha &da) {
  // [t, q, v, a, acc, lambda (this rank's entries), substeps, (dt, t, the five)...].
  auto add = [](std::vector<double> &out, const dynamics::DistState &s) {
    out.push_back(s.t);
    for (Vec v : {s.q, s.v, s.a, s.acc, s.lambda}) {
      PetscInt n = 0;
      const PetscScalar *a;
      FX_PETSC(VecGetLocalSize(v, &n));
      FX_PETSC(VecGetArrayRead(v, &a));
      out.insert(out.end(), a, a + n);
      FX_PETSC(VecRestoreArrayRead(v, &a));
    }
  };
  Codec<DistRecord> codec;
  codec.pack = [add](const DistRecord &r) {
    std::vector<double> out;
    add(out, r.state);
    out.push_back(static_cast<double>(r.substeps.size()));
    for (const auto &[s, dt] : r.substeps) {
      out.push_back(dt);
      add(out, s);
    }
    return out;
  };
  codec.unpack = [&da](const std::vector<double> &d) {
    std::size_t pos = 0;
    auto take = [&]() {
      dynamics::DistState s = da.zero_state();
      s.t = d[pos++];
      for (Vec v : {s.q, s.v, s.a, s.acc, s.lambda}) {
        PetscInt n = 0;
        PetscScalar *a;
        FX_PETSC(VecGetLocalSize(v, &n));
        FX_PETSC(VecGetArray(v, &a));
        std::copy(d.begin() + static_cast<std::ptrdiff_t>(pos),
                  d.begin() + static_cast<std::ptrdiff_t>(pos) + n, a);
        FX_PETSC(VecRestoreArray(v, &a));
        pos += static_cast<std::size_t>(n);
      }
      return s;
    };
    return unpack_record<DistRecord>(d, pos, take);
  };
  return std::make_unique<DiskStore<DistRecord>>(path, std::move(codec));
}

} // namespace flexopt::adjoint
