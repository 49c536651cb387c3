#pragma once
// Shared by the BSDF tests (bsdf_test.cpp, microfacet_test.cpp): directions, the χ² test of
// Sample against Pdf over a binned sphere (in the style of pbrt's bsdfs_test) and the white
// furnace estimate of an albedo.

#include <gtest/gtest.h>

#include <algorithm>
#include <cmath>
#include <functional>
#include <numbers>
#include <string>
#include <utility>
#include <vector>

#include "common/core/rng.h"
#include "common/materials/bsdf.h"

namespace pf::bsdf_test {

inline constexpr double kPiD = std::numbers::pi;

// FNV-1a: a seed per case name that does not depend on the standard library's std::hash.
inline uint64_t NameSeed(const std::string& name) {
  uint64_t h = 0xcbf29ce484222325ull;
  for (unsigned char ch : name) h = (h ^ ch) * 0x100000001b3ull;
  return h;
}

inline Vec3 Spherical(double theta, double phi) {
  return Vec3(float(std::sin(theta) * std::cos(phi)), float(std::sin(theta) * std::sin(phi)),
              float(std::cos(theta)));
}

// A direction with cos θ = c (against +z) at azimuth phi.
inline Vec3 FromCos(float c, float phi = 0.3f) {
  const float s = std::sqrt(std::max(0.0f, 1.0f - c * c));
  return {s * std::cos(phi), s * std::sin(phi), c};
}

inline Vec3 UniformSphere(Rng& rng) {
  const float z = 1.0f - 2.0f * rng.Uniform();
  const float r = std::sqrt(std::max(0.0f, 1.0f - z * z));
  const float phi = kTwoPi * rng.Uniform();
  return {r * std::cos(phi), r * std::sin(phi), z};
}

// ---------------------------------------------------------------------------------------------
// χ² machinery.

// Regularised upper incomplete gamma Q(a, x) (series for x < a + 1, Lentz's continued fraction
// otherwise), enough for χ² p-values: p = Q(dof/2, χ²/2).
inline double GammaQ(double a, double x) {
  if (x <= 0) return 1.0;
  const double log_prefix = -x + a * std::log(x) - std::lgamma(a);
  if (x < a + 1) {
    double term = 1.0 / a, sum = term;
    for (int n = 1; n < 10000; ++n) {
      term *= x / (a + n);
      sum += term;
      if (std::abs(term) < std::abs(sum) * 1e-15) break;
    }
    return std::max(0.0, 1.0 - sum * std::exp(log_prefix));
  }
  const double tiny = 1e-300;
  double b = x + 1 - a, c = 1 / tiny, d = 1 / b, h = d;
  for (int i = 1; i < 10000; ++i) {
    const double an = -i * (i - a);
    b += 2;
    d = an * d + b;
    if (std::abs(d) < tiny) d = tiny;
    c = b + an / c;
    if (std::abs(c) < tiny) c = tiny;
    d = 1 / d;
    const double delta = d * c;
    h *= delta;
    if (std::abs(delta - 1) < 1e-15) break;
  }
  return std::exp(log_prefix) * h;
}

struct ChiSquareResult {
  double p_value = 0;
  int dof = 0;
  double chi2 = 0;
  std::string error;  // non-empty: samples where the pdf is zero
};

// Pearson's test; cells with an expected count below 5 are pooled (pbrt's rule).
inline ChiSquareResult ChiSquare(const std::vector<double>& observed, const std::vector<double>& expected,
                                 double total) {
  ChiSquareResult r;
  std::vector<size_t> order(observed.size());
  for (size_t i = 0; i < order.size(); ++i) order[i] = i;
  std::sort(order.begin(), order.end(), [&](size_t a, size_t b) { return expected[a] < expected[b]; });
  constexpr double kMinExpected = 5.0;
  double pooled_obs = 0, pooled_exp = 0;
  std::vector<std::pair<double, double>> cells;  // (observed, expected)
  for (size_t i : order) {
    if (expected[i] <= 1e-12 * total) {
      if (observed[i] > 1e-5 * total) {
        r.error = "cell " + std::to_string(i) + ": " + std::to_string(observed[i]) +
                  " samples where the pdf integrates to zero";
        return r;
      }
      pooled_obs += observed[i];
      continue;
    }
    if (expected[i] < kMinExpected) {
      pooled_obs += observed[i];
      pooled_exp += expected[i];
    } else {
      cells.emplace_back(observed[i], expected[i]);
    }
  }
  if (pooled_exp > 0 || pooled_obs > 0) {
    if (pooled_exp < kMinExpected && !cells.empty()) {
      cells.front().first += pooled_obs;  // the smallest regular cell (sorted ascending)
      cells.front().second += pooled_exp;
    } else {
      cells.emplace_back(pooled_obs, pooled_exp);
    }
  }
  for (const auto& [o, e] : cells) r.chi2 += (o - e) * (o - e) / e;
  r.dof = int(cells.size()) - 1;
  r.p_value = r.dof > 0 ? GammaQ(0.5 * r.dof, 0.5 * r.chi2) : 1.0;
  return r;
}

// One χ² case: a material, wo, the shading normal (the geometric one is +z) and the mode.
struct ChiCase {
  std::string name;
  Material material;
  Vec3 wo;
  Vec3 ns = Vec3(0, 0, 1);
  // kRussianRoulette (the particle walks' mode, with its own cosine-lobe azimuth): the survivors'
  // directions have the density RouletteProbability·Pdf; the absorbed join the rejected cell.
  Bsdf::Mode mode = Bsdf::Mode::kNormalized;
};

struct SamplingChiSquare {
  ChiSquareResult r;
  double total = 0;     // the pdf's mass over the sphere (times the survival in the roulette)
  double rejected = 0;  // fraction of samples rejected or absorbed
};

// Draws `samples` directions from bsdf.Sample(wo, ·, mode) (seeded by `name`) and compares their
// histogram over 24 × 48 (θ, φ) bins of the sphere (+ one cell for the rejected) with Pdf, times
// RouletteProbability in kRussianRoulette (whose survivors have that density). A delta sample is
// an error.
inline SamplingChiSquare SampleChiSquare(const Bsdf& bsdf, const Vec3& wo, Bsdf::Mode mode,
                                         const std::string& name, int samples = 1'000'000) {
  SamplingChiSquare out;
  constexpr int kThetaBins = 24, kPhiBins = 48;
  const int num_bins = kThetaBins * kPhiBins;

  // Observed: one extra cell for rejected samples.
  std::vector<double> observed(num_bins + 1, 0.0), expected(num_bins + 1, 0.0);
  // θ bins by z against the bins' cosines (acos per sample would dominate the test's time).
  std::vector<float> bin_cos(kThetaBins + 1);  // decreasing
  for (int t = 0; t <= kThetaBins; ++t) bin_cos[t] = float(std::cos(t * kPiD / kThetaBins));
  Rng rng(0x5eed, NameSeed(name));
  for (int i = 0; i < samples; ++i) {
    const float ul = rng.Uniform(), u1 = rng.Uniform(), u2 = rng.Uniform();
    const auto s = bsdf.Sample(wo, ul, u1, u2, mode);
    if (!s) {
      observed[num_bins] += 1;
      continue;
    }
    if (s->is_delta) {
      out.r.error = "a delta sample";
      return out;
    }
    const int ti =
        std::clamp(int(std::upper_bound(bin_cos.begin(), bin_cos.end(), s->wi.z, std::greater<float>()) -
                       bin_cos.begin()) -
                       1,
                   0, kThetaBins - 1);
    float phi = std::atan2(s->wi.y, s->wi.x);
    if (phi < 0) phi += kTwoPi;
    const int pi = std::min(kPhiBins - 1, int(phi * (kPhiBins / kTwoPi)));
    observed[ti * kPhiBins + pi] += 1;
  }

  // Expected: per bin, composite Simpson of Pdf·sinθ, refined (8, 16, 32, ... intervals per
  // side) until two successive levels agree; nodes are pulled in from the bin edges by a hair
  // so that θ = π/2 (the discontinuity at the surface plane) is never evaluated.
  const double dt = kPiD / kThetaBins, dp = 2 * kPiD / kPhiBins;
  const double survival =
      mode == Bsdf::Mode::kRussianRoulette ? double(bsdf.RouletteProbability(wo, kLobeAll)) : 1.0;
  auto simpson = [&](double t0, double t1, double p0, double p1, int sub) {
    const double ht = (t1 - t0) / sub, hp = (p1 - p0) / sub;
    std::vector<double> cp(sub + 1), sp(sub + 1);
    for (int b = 0; b <= sub; ++b) {
      cp[b] = std::cos(p0 + b * hp);
      sp[b] = std::sin(p0 + b * hp);
    }
    double sum = 0;
    for (int a = 0; a <= sub; ++a) {
      const double wa = (a == 0 || a == sub) ? 1 : (a % 2 ? 4 : 2);
      const double st = std::sin(t0 + a * ht), ct = std::cos(t0 + a * ht);
      double row = 0;
      for (int b = 0; b <= sub; ++b) {
        const double wb = (b == 0 || b == sub) ? 1 : (b % 2 ? 4 : 2);
        const Vec3 wi(float(st * cp[b]), float(st * sp[b]), float(ct));
        row += wb * bsdf.Pdf(wo, wi);
      }
      sum += wa * st * row;
    }
    return sum * ht * hp / 9.0;
  };
  double total = 0;
  for (int ti = 0; ti < kThetaBins; ++ti) {
    for (int pi = 0; pi < kPhiBins; ++pi) {
      const double t0 = ti * dt + 1e-7, t1 = (ti + 1) * dt - 1e-7;
      const double p0 = pi * dp, p1 = (pi + 1) * dp;
      double coarse = simpson(t0, t1, p0, p1, 8);
      double fine = simpson(t0, t1, p0, p1, 16);
      for (int sub = 32; sub <= 256 && std::abs(fine - coarse) > std::max(1e-4 * fine, 1e-8); sub *= 2) {
        coarse = fine;
        fine = simpson(t0, t1, p0, p1, sub);
      }
      expected[ti * kPhiBins + pi] = fine * survival * samples;
      total += fine * survival;
    }
  }
  expected[num_bins] = std::max(0.0, 1.0 - total) * samples;

  out.r = ChiSquare(observed, expected, samples);
  out.total = total;
  out.rejected = observed[num_bins] / samples;
  return out;
}

// ---------------------------------------------------------------------------------------------
// Sample's weight and pdf against Eval and Pdf (kNormalized) for `n` uniform wo: weight =
// Eval·|cos θi|/Pdf and pdf = Pdf, relative 1e-4. Delta samples are skipped (`delta` counts them).
// Returns the number of samples checked; stops at the first mismatch (a test failure).
inline int ExpectWeightsMatchEvalAndPdf(const Bsdf& bsdf, Rng& rng, int n, int* delta = nullptr) {
  int checked = 0;
  for (int i = 0; i < n; ++i) {
    const Vec3 wo = UniformSphere(rng);
    const auto s = bsdf.Sample(wo, rng.Uniform(), rng.Uniform(), rng.Uniform());
    if (!s) continue;
    if (s->is_delta) {
      if (delta) ++*delta;
      continue;
    }
    const float pdf = bsdf.Pdf(wo, s->wi);
    const Rgb f = bsdf.Eval(wo, s->wi);
    EXPECT_GT(pdf, 0.0f);
    EXPECT_NEAR(s->pdf, pdf, 1e-4f * pdf);
    for (int ch = 0; ch < 3; ++ch) {
      const float expected = f[ch] * bsdf.AbsCosTheta(s->wi) / pdf;
      EXPECT_NEAR(s->weight[ch], expected, 1e-4f * std::max(expected, 1e-3f));
    }
    if (::testing::Test::HasFailure()) return checked;
    ++checked;
  }
  return checked;
}

// ---------------------------------------------------------------------------------------------
// White furnace: albedo = E[weight] with ρ = 1 (or τ = 1).

struct Albedo {
  double mean[3] = {0, 0, 0};
  double sigma[3] = {0, 0, 0};  // standard error
  double survival = 0;
};

inline Albedo EstimateAlbedo(const Bsdf& bsdf, const Vec3& wo, int n, uint64_t seed,
                             Bsdf::Mode mode = Bsdf::Mode::kNormalized) {
  Rng rng(seed, 99);
  double sum[3] = {0, 0, 0}, sum2[3] = {0, 0, 0};
  int survived = 0;
  for (int i = 0; i < n; ++i) {
    const float ul = rng.Uniform(), u1 = rng.Uniform(), u2 = rng.Uniform();
    const auto s = bsdf.Sample(wo, ul, u1, u2, mode);
    if (!s) continue;
    ++survived;
    for (int ch = 0; ch < 3; ++ch) {
      sum[ch] += s->weight[ch];
      sum2[ch] += double(s->weight[ch]) * s->weight[ch];
    }
  }
  Albedo a;
  for (int ch = 0; ch < 3; ++ch) {
    a.mean[ch] = sum[ch] / n;
    a.sigma[ch] = std::sqrt(std::max(0.0, sum2[ch] / n - a.mean[ch] * a.mean[ch]) / n);
  }
  a.survival = double(survived) / n;
  return a;
}

}  // namespace pf::bsdf_test
