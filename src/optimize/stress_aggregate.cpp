#include "flexopt/optimize/stress_aggregate.hpp"

#include <algorithm>
#include <climits>
#include <cmath>

namespace flexopt::optimize {

namespace {
/// x^p for x >= 0: by repeated squaring when p is a whole number up to 64 (every sample of a
/// dynamic aggregate takes one; std::pow costs ten times more), else std::pow.
double power(double x, double p) {
  if (p == std::floor(p) && p >= 0 && p <= 64) {
    auto n = static_cast<unsigned>(p);
    double r = 1.0, b = x;
    while (n) {
      if (n & 1u) r *= b;
      b *= b;
      n >>= 1u;
    }
    return r;
  }
  return std::pow(x, p);
}
} // namespace

void StressAggregate::clear() {
  local_peak_ = 0;
  local_sum_ = 0;
  local_time_ = -1;
  local_tag_ = -1;
  value_ = peak_ = sum_ = 0;
  peak_time_ = -1;
  peak_tag_ = -1;
}

double StressAggregate::rescale(double from, double to) const {
  if (s_.type == StressAggregateType::Ks) return std::exp(s_.ks * (from - to) / s_.reference);
  return to > 0 ? power(from / to, s_.p) : 1.0;
}

double StressAggregate::term(double sigma, double weight, double m) const {
  if (s_.type == StressAggregateType::Ks)
    return weight * std::exp(s_.ks * (sigma - m) / s_.reference);
  return m > 0 ? weight * power(sigma / m, s_.p) : 0.0;
}

void StressAggregate::add(double sigma, double weight, long long tag, double time) {
  if (local_tag_ < 0 || sigma > local_peak_) { // a new running peak: the sum so far follows it
    if (local_tag_ >= 0) local_sum_ *= rescale(local_peak_, sigma);
    local_peak_ = sigma;
    local_tag_ = tag;
    local_time_ = time;
  } else if (sigma == local_peak_ && tag < local_tag_) {
    local_tag_ = tag; // ties: the lowest tag (its first time)
    local_time_ = time;
  }
  local_sum_ += term(sigma, weight, local_peak_);
}

void StressAggregate::reduce(MPI_Comm comm) {
  MPI_Allreduce(&local_peak_, &peak_, 1, MPI_DOUBLE, MPI_MAX, comm);
  double sum = local_sum_ * rescale(local_peak_, peak_);
  MPI_Allreduce(&sum, &sum_, 1, MPI_DOUBLE, MPI_SUM, comm);
  // The peak's place: the lowest tag among the ranks that hold it, then its earliest time.
  long long tag = local_tag_ >= 0 && local_peak_ == peak_ ? local_tag_ : LLONG_MAX;
  MPI_Allreduce(&tag, &peak_tag_, 1, MPI_LONG_LONG, MPI_MIN, comm);
  double time = tag == peak_tag_ ? local_time_ : HUGE_VAL;
  MPI_Allreduce(&time, &peak_time_, 1, MPI_DOUBLE, MPI_MIN, comm);
  if (peak_tag_ == LLONG_MAX) { // no samples anywhere
    peak_tag_ = -1;
    peak_time_ = -1;
  }
  if (s_.type == StressAggregateType::Ks)
    value_ = sum_ > 0 ? peak_ + s_.reference * std::log(sum_) / s_.ks : 0.0;
  else
    value_ = sum_ > 0 ? peak_ * std::pow(sum_, 1.0 / s_.p) : 0.0;
}

double StressAggregate::derivative(double sigma, double weight) const {
  if (!(sum_ > 0)) return 0.0;
  if (s_.type == StressAggregateType::Ks)
    return weight * std::exp(s_.ks * (sigma - peak_) / s_.reference) / sum_;
  return value_ > 0 ? weight * power(sigma / value_, s_.p - 1) : 0.0;
}

} // namespace flexopt::optimize
