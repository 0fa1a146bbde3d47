// A small seeded random source for the synthetic actor. The standard
// distributions (std::normal_distribution, ...) are implementation-defined,
// so the same seed could give different actors with different standard
// libraries; these draws are fully specified (SplitMix64, Steele et al. 2014;
// Box-Muller for normals).
#pragma once

#include <cmath>
#include <cstdint>

namespace hmc {

class SynthRandom {
 public:
  explicit SynthRandom(uint64_t seed) : state_(seed * 0x9E3779B97F4A7C15ULL + 0x632BE59BD9B4E019ULL) {}

  // A stream derived from this seed and a label, so adding draws to one part
  // of the generator does not shift the draws of another.
  static SynthRandom Stream(uint64_t seed, uint64_t label) {
    SynthRandom mix(seed ^ (label * 0xD1B54A32D192ED03ULL));
    return SynthRandom(mix.Next());
  }

  uint64_t Next() {
    uint64_t z = (state_ += 0x9E3779B97F4A7C15ULL);
    z = (z ^ (z >> 30)) * 0xBF58476D1CE4E5B9ULL;
    z = (z ^ (z >> 27)) * 0x94D049BB133111EBULL;
    return z ^ (z >> 31);
  }

  // Uniform in [0, 1).
  double Uniform() { return static_cast<double>(Next() >> 11) * 0x1.0p-53; }
  double Uniform(double lo, double hi) { return lo + (hi - lo) * Uniform(); }
  // Uniform integer in [0, n).
  int Index(int n) { return static_cast<int>(Uniform() * n); }
  // Standard normal (Box-Muller).
  double Normal() {
    const double u1 = 1.0 - Uniform();  // (0, 1]
    const double u2 = Uniform();
    return std::sqrt(-2.0 * std::log(u1)) * std::cos(2.0 * M_PI * u2);
  }

 private:
  uint64_t state_;
};

}  // namespace hmc
