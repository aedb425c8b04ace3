// A fixed-size log-linear histogram (HDR-style) of non-negative durations,
// for the controller's statistics over a whole run of any length: no
// allocation after construction, no cap on the number of samples, exact
// count and maximum, quantiles within 1/128 relative (2^7 sub-buckets per
// octave) from 1 ns to 2^63 ns. Header-only, no I/O, no clock.
#pragma once

#include <array>
#include <cmath>
#include <cstdint>

namespace sc_rt {

class LogHistogram {
 public:
  static constexpr int kSubBits = 7;                           //!< 2^7 sub-buckets per octave
  static constexpr std::uint64_t kSub = 1ull << kSubBits;      //!< values below this are exact
  static constexpr int kBuckets = (64 - kSubBits + 1) << kSubBits;

  //! One sample [us] (negative and NaN count as 0; +inf as the largest bucket).
  void add(double us) {
    double ns = us * 1e3;
    if (!(ns > 0.0)) ns = 0.0;
    const std::uint64_t u = ns >= 9.2e18 ? (1ull << 63) : static_cast<std::uint64_t>(ns + 0.5);
    ++counts_[index(u)];
    ++n_;
    if (us > max_ || n_ == 1) max_ = us > 0.0 ? us : 0.0;
    sum_ += us > 0.0 ? us : 0.0;
  }

  std::uint64_t count() const { return n_; }
  double max() const { return max_; }  //!< [us], exact
  double mean() const { return n_ ? sum_ / double(n_) : 0.0; }

  //! The nearest-rank p-quantile [us] (p in [0, 1]): the middle of its
  //! bucket, never above the exact maximum; 0 without samples.
  double quantile(double p) const {
    if (n_ == 0) return 0.0;
    const double want = std::ceil(p * double(n_));
    const std::uint64_t rank = want < 1.0 ? 1 : static_cast<std::uint64_t>(want);
    std::uint64_t seen = 0;
    for (int i = 0; i < kBuckets; ++i) {
      seen += counts_[i];
      if (seen >= rank) {
        const double mid = (double(lower(i)) + 0.5 * double(width(i)) - (width(i) == 1 ? 0.5 : 0.0)) / 1e3;
        return mid < max_ ? mid : max_;
      }
    }
    return max_;
  }

  static int index(std::uint64_t u) {
    if (u < kSub) return static_cast<int>(u);
    const int h = 63 - __builtin_clzll(u);  // >= kSubBits
    const int octave = h - kSubBits + 1;
    const std::uint64_t mantissa = (u >> (h - kSubBits)) & (kSub - 1);
    return static_cast<int>((static_cast<std::uint64_t>(octave) << kSubBits) | mantissa);
  }
  static std::uint64_t lower(int i) {  //!< [ns] the smallest value of bucket i
    const int octave = i >> kSubBits;
    const std::uint64_t mantissa = static_cast<std::uint64_t>(i) & (kSub - 1);
    return octave == 0 ? mantissa : (kSub + mantissa) << (octave - 1);
  }
  static std::uint64_t width(int i) {  //!< [ns] its width
    const int octave = i >> kSubBits;
    return octave == 0 ? 1 : 1ull << (octave - 1);
  }

 private:
  std::array<std::uint64_t, kBuckets> counts_{};
  std::uint64_t n_ = 0;
  double max_ = 0.0, sum_ = 0.0;
};

}  // namespace sc_rt
