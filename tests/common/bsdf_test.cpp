// Tests of common/materials/bsdf.h: the sampling routines against their pdfs (χ², in the
// style of pbrt's bsdfs_test), reciprocity, energy conservation per lobe (white furnace),
// weight/Eval/Pdf consistency, Russian roulette, Fresnel and sidedness.
//
// Coordinates: the geometric normal is +z unless a test says otherwise, so θ = π/2 (a χ² bin
// edge) is exactly the surface plane.

#include "common/materials/bsdf.h"

#include <gtest/gtest.h>

#include <algorithm>
#include <bit>
#include <cctype>
#include <cmath>
#include <cstdio>
#include <functional>
#include <numbers>
#include <string>
#include <vector>

#include "common/core/rng.h"
#include "tests/common/bsdf_test_support.h"

namespace pf {
namespace {

using namespace pf::bsdf_test;  // the shared BSDF test helpers (bsdf_test_support.h)

constexpr Vec3 kUp{0, 0, 1};

Material Diffuse(float rho) {
  Material m;
  m.diffuse_reflectance = Rgb(rho);
  return m;
}
Material Glossy(float rho, float alpha) {
  Material m;
  m.specular_reflectance = Rgb(rho);
  m.specular_roughness = alpha;
  return m;
}
Material Dielectric(float tau, float ior) {
  Material m;
  m.specular_transmittance = Rgb(tau);
  m.ior = ior;
  return m;
}

// ---------------------------------------------------------------------------------------------
// χ² machinery (bsdf_test_support.h).

TEST(BsdfChiSquareMachinery, GammaQMatchesKnownValues) {
  // χ² with 2 dof: p = exp(−x/2). χ² with 1 dof at 3.841459: p = 0.05. 10 dof at 23.209: 0.01.
  EXPECT_NEAR(GammaQ(1.0, 2.5), std::exp(-2.5), 1e-12);
  EXPECT_NEAR(GammaQ(0.5, 3.841459 / 2), 0.05, 1e-6);
  EXPECT_NEAR(GammaQ(5.0, 23.20925 / 2), 0.01, 1e-6);
  EXPECT_NEAR(GammaQ(200.0, 200.0), 0.4906, 1e-3);
}

std::vector<ChiCase> ChiCases() {
  std::vector<ChiCase> cases;
  cases.push_back({"diffuse_normal", Diffuse(0.8f), FromCos(0.99f)});
  cases.push_back({"diffuse_grazing", Diffuse(0.8f), FromCos(0.05f)});
  const float alphas[] = {0.05f, 0.2f, 0.5f};
  const float cosines[] = {0.98f, 0.7f, 0.17f};  // θo ≈ 11°, 46°, 80°
  for (float a : alphas) {
    for (float c : cosines) {
      char name[64];
      std::snprintf(name, sizeof(name), "glossy_a%.2f_cos%.2f", a, c);
      cases.push_back({name, Glossy(0.9f, a), FromCos(c)});
    }
  }
  {
    Material m;
    m.diffuse_transmittance = Rgb(0.7f);
    cases.push_back({"diffuse_transmission", m, FromCos(0.6f)});
  }
  {
    Material m = Glossy(0.3f, 0.2f);
    m.diffuse_reflectance = Rgb(0.5f);
    cases.push_back({"diffuse+glossy0.2_cos0.8", m, FromCos(0.8f)});
    cases.push_back({"diffuse+glossy0.2_cos0.3", m, FromCos(0.3f)});
  }
  {
    Material m = Glossy(0.6f, 0.05f);
    m.diffuse_reflectance = Rgb(0.2f, 0.3f, 0.1f);
    m.diffuse_transmittance = Rgb(0.2f);
    cases.push_back({"diffuse+glossy0.05+difftrans", m, FromCos(0.5f, 2.0f)});
  }
  {
    Material m = Glossy(0.5f, 0.3f);
    m.diffuse_reflectance = Rgb(0.4f);
    // Shading normal tilted 25° away from ng: the lobes follow ns, and samples that land
    // below ng are rejected.
    const Vec3 tilted(std::sin(0.436f), 0.0f, std::cos(0.436f));
    cases.push_back({"tilted_shading_normal", m, FromCos(0.35f, 0.3f), tilted});
    // wo below the shading hemisphere (wo·ns < 0): the lobes fall back to ng.
    cases.push_back({"tilted_shading_normal_fallback", m, FromCos(0.35f, 3.0f), tilted});
  }
  cases.push_back({"glossy_back_side", Glossy(0.9f, 0.2f), FromCos(-0.6f, 1.0f)});
  // The particle walks' sampling of every case with a diffuse lobe (bsdf.cpp: polynomial azimuth,
  // analytic ρ/P weight).
  const size_t normalized = cases.size();
  for (size_t i = 0; i < normalized; ++i) {
    ChiCase c = cases[i];
    if (c.material.diffuse_reflectance.IsBlack() && c.material.diffuse_transmittance.IsBlack()) continue;
    c.name += "_roulette";
    c.mode = Bsdf::Mode::kRussianRoulette;
    cases.push_back(c);
  }
  return cases;
}

class BsdfChiSquareTest : public testing::TestWithParam<ChiCase> {};

TEST_P(BsdfChiSquareTest, SampleMatchesPdf) {
  const ChiCase& c = GetParam();
  const Bsdf bsdf(c.material, c.ns, kUp);
  const Vec3 wo = Normalize(c.wo);
  const SamplingChiSquare chi = SampleChiSquare(bsdf, wo, c.mode, c.name);
  const ChiSquareResult& r = chi.r;
  ASSERT_TRUE(r.error.empty()) << r.error;
  const double significance = 1.0 - std::pow(1.0 - 0.01, 1.0 / double(ChiCases().size()));
  std::printf("[chi2] %-32s pdf mass %.5f  rejected %.5f  chi2 %.1f dof %d  p = %.4f\n", c.name.c_str(),
              chi.total, chi.rejected, r.chi2, r.dof, r.p_value);
  EXPECT_GT(r.p_value, significance) << c.name << ": χ² = " << r.chi2 << " with " << r.dof
                                     << " dof (Šidák-corrected level " << significance << ")";
}

INSTANTIATE_TEST_SUITE_P(Bsdf, BsdfChiSquareTest, testing::ValuesIn(ChiCases()),
                         [](const testing::TestParamInfo<ChiCase>& info) {
                           std::string n = info.param.name;
                           for (char& ch : n) {
                             if (!std::isalnum(static_cast<unsigned char>(ch))) ch = '_';
                           }
                           return n;
                         });

// A sampler that skews its directions must fail the same machinery (the test can fail).
TEST(BsdfChiSquareMachinery, DetectsAWrongSampler) {
  // Cosine-distributed samples compared against a uniform-hemisphere pdf.
  constexpr int kBins = 24, kSamples = 200'000;
  std::vector<double> observed(kBins, 0), expected(kBins, 0);
  Rng rng(7, 7);
  for (int i = 0; i < kSamples; ++i) {
    const float z = std::sqrt(1.0f - rng.Uniform());
    observed[std::min(kBins - 1, int(z * kBins))] += 1;
  }
  for (int b = 0; b < kBins; ++b) expected[b] = double(kSamples) / kBins;
  EXPECT_LT(ChiSquare(observed, expected, kSamples).p_value, 1e-6);
}

// ---------------------------------------------------------------------------------------------

TEST(BsdfReciprocity, EvalIsSymmetricForReflectionAndDiffuseTransmission) {
  // Tolerance: relative 1e-5 (the formulas are symmetric; only rounding may differ).
  Material mix = Glossy(0.4f, 0.15f);
  mix.diffuse_reflectance = Rgb(0.3f, 0.2f, 0.1f);
  mix.diffuse_transmittance = Rgb(0.1f, 0.2f, 0.3f);
  const Vec3 tilted = Normalize(Vec3(0.3f, -0.2f, 1.0f));
  const struct {
    Material m;
    Vec3 ns;
  } cases[] = {{Glossy(1.0f, 0.05f), kUp}, {Glossy(1.0f, 0.5f), kUp}, {mix, kUp}, {mix, tilted}};
  Rng rng(11, 3);
  int checked = 0, nonzero = 0;
  for (const auto& c : cases) {
    const Bsdf bsdf(c.m, c.ns, kUp);
    for (int i = 0; i < 20000; ++i) {
      const Vec3 wo = UniformSphere(rng);
      Vec3 wi = UniformSphere(rng);
      if (i % 2 == 0) {  // half of the pairs near the specular direction, where the lobe is large
        const Vec3 n = Dot(wo, kUp) > 0 ? kUp : -kUp;
        wi = Normalize(n * (2 * Dot(wo, n)) - wo + UniformSphere(rng) * 0.1f);
      }
      // With a tilted shading normal the lobe frame depends on wo's side of ns too (fallback
      // to ng below the shading hemisphere): reciprocity holds when both are above it.
      const Vec3 ns_side = Dot(wo, kUp) > 0 ? c.ns : -c.ns;
      if (Dot(wo, ns_side) * Dot(wi, ns_side) <= 0 && Dot(wo, kUp) * Dot(wi, kUp) > 0) continue;
      const Rgb a = bsdf.Eval(wo, wi), b = bsdf.Eval(wi, wo);
      for (int ch = 0; ch < 3; ++ch) {
        ASSERT_NEAR(a[ch], b[ch], 1e-5f * std::max(std::abs(a[ch]), 1e-6f))
            << "wo " << wo.x << " " << wo.y << " " << wo.z << " wi " << wi.x << " " << wi.y << " " << wi.z;
      }
      ++checked;
      nonzero += !a.IsBlack();
    }
  }
  EXPECT_GT(checked, 60000);
  EXPECT_GT(nonzero, 30000);
}

// ---------------------------------------------------------------------------------------------
// White furnace: albedo = E[weight] with ρ = 1 (or τ = 1).

constexpr float kFurnaceCosines[] = {1.0f, 0.7f, 0.3f, 0.1f, 0.01f, 1e-3f, 1e-4f};

TEST(BsdfEnergy, DiffuseReflectionAndTransmissionAlbedoIsOne) {
  Material t;
  t.diffuse_transmittance = Rgb(1.0f);
  for (const Material& m : {Diffuse(1.0f), t}) {
    const Bsdf bsdf(m, kUp, kUp);
    for (float c : kFurnaceCosines) {
      const Albedo a = EstimateAlbedo(bsdf, FromCos(c), 50'000, 1);
      std::printf("[furnace] %s cos %g albedo %.5f\n",
                  m.diffuse_reflectance.IsBlack() ? "diffuse-T" : "diffuse-R", c, a.mean[0]);
      EXPECT_NEAR(a.mean[0], 1.0, 0.01) << "cos " << c;
    }
  }
}

TEST(BsdfEnergy, GlossyAlbedoNeverExceedsOne) {
  for (float alpha : {0.05f, 0.2f, 0.5f, 1.0f}) {
    const Material m = Glossy(1.0f, alpha);
    const Bsdf bsdf(m, kUp, kUp);
    for (float c : kFurnaceCosines) {
      const Albedo a = EstimateAlbedo(bsdf, FromCos(c), 50'000, 2);
      std::printf("[furnace] glossy a=%.2f cos %g albedo %.5f ± %.5f\n", alpha, c, a.mean[0], a.sigma[0]);
      EXPECT_LE(a.mean[0], 1.0 + 3 * a.sigma[0]) << "α " << alpha << " cos " << c;
      EXPECT_GT(a.mean[0], 0.0);
    }
    // Normal incidence has a closed form (weight = 1 − tan²δ for tan²δ < 1, else rejected):
    // albedo = 1 − α²(1 − exp(−1/α²)). Pins the absolute normalisation of the lobe.
    const Albedo a = EstimateAlbedo(bsdf, kUp, 50'000, 3);
    const double a2 = double(alpha) * alpha;
    const double expected = 1.0 - a2 * (1.0 - std::exp(-1.0 / a2));
    EXPECT_NEAR(a.mean[0], expected, 4 * a.sigma[0] + 1e-5) << "α " << alpha;
  }
}

TEST(BsdfEnergy, MirrorThinAndDielectricWeights) {
  // Mirror and thin transmission: weight exactly 1 for ρ = 1 / τ = 1.
  Material thin;
  thin.specular_transmittance = Rgb(1.0f);
  for (const Material& m : {Glossy(1.0f, 0.0f), thin}) {
    const Bsdf bsdf(m, kUp, kUp);
    for (float c : kFurnaceCosines) {
      const auto s = bsdf.Sample(FromCos(c), 0.5f, 0.5f, 0.5f);
      ASSERT_TRUE(s.has_value());
      EXPECT_TRUE(s->is_delta);
      EXPECT_EQ(s->weight, Rgb(1.0f));
    }
  }
  // Dielectric with τs = 1: every weight is 1 (reflection untinted, refraction τs), so
  // E[weight] = F + (1 − F) = 1; the reflected fraction is F.
  for (float ior : {1.5f, 1.0f / 1.33f}) {
    const Bsdf bsdf(Dielectric(1.0f, ior), kUp, kUp);
    for (float c : kFurnaceCosines) {
      for (float side : {1.0f, -1.0f}) {
        const Vec3 wo = FromCos(side * c);
        Rng rng(5, 5);
        const int n = 20'000;
        int reflected = 0;
        double sum = 0;
        for (int i = 0; i < n; ++i) {
          const auto s = bsdf.Sample(wo, rng.Uniform(), rng.Uniform(), rng.Uniform());
          ASSERT_TRUE(s.has_value());
          sum += s->weight[0];
          reflected += s->lobe == kLobeSpecularReflection;
        }
        const float eta = side > 0 ? ior : 1.0f / ior;
        const double f = FresnelDielectric(c, eta);
        EXPECT_NEAR(sum / n, 1.0, 1e-6);
        EXPECT_NEAR(double(reflected) / n, f, 4 * std::sqrt(f * (1 - f) / n) + 1e-9)
            << "ior " << ior << " cos " << c << " side " << side;
      }
    }
  }
}

// ---------------------------------------------------------------------------------------------

TEST(BsdfConsistency, WeightEqualsEvalCosOverPdf) {
  Material mix = Glossy(0.4f, 0.1f);
  mix.diffuse_reflectance = Rgb(0.5f, 0.2f, 0.1f);
  mix.diffuse_transmittance = Rgb(0.05f, 0.1f, 0.2f);
  mix.specular_transmittance = Rgb(0.1f);  // thin: a delta lobe in the mixture
  Material dm = Glossy(0.5f, 0.0f);        // mirror + diffuse
  dm.diffuse_reflectance = Rgb(0.4f);
  const Vec3 tilted = Normalize(Vec3(0.4f, 0.1f, 1.0f));
  const struct {
    Material m;
    Vec3 ns;
  } cases[] = {{Diffuse(0.7f), kUp},
               {Glossy(0.8f, 0.05f), kUp},
               {Glossy(0.8f, 0.5f), tilted},
               {mix, kUp},
               {mix, tilted},
               {dm, kUp}};
  Rng rng(21, 4);
  int checked = 0;
  for (const auto& c : cases) {
    const Bsdf bsdf(c.m, c.ns, kUp);
    checked += ExpectWeightsMatchEvalAndPdf(bsdf, rng, 20000);
    ASSERT_FALSE(HasFailure());
  }
  EXPECT_GT(checked, 80000);
}

// The particle walks' weights and pdfs (kRussianRoulette) agree with Eval and Pdf: weight =
// f_lobe·|cos θi|/pdf and pdf = P_lobe·pdf_lobe, for the diffuse lobes' analytic ρ/P (lobe axis =
// shading normal) and for the fallback through EvalPdf (wo below the shading hemisphere, where
// |cos θi| is taken against ns, not the axis). Relative 1e-4: the analytic ρ/P and the quotient
// differ only by rounding; a weight of ρ/P where the fallback is due is off by |wi·ns|/|wi·ng|.
TEST(BsdfConsistency, RouletteWeightEqualsEvalCosOverPdf) {
  Material dt;
  dt.diffuse_transmittance = Rgb(0.6f, 0.3f, 0.2f);
  const Vec3 tilted = Normalize(Vec3(0.6f, 0.1f, 1.0f));
  const Material cases[] = {Diffuse(0.7f), dt};
  Rng rng(23, 8);
  int checked = 0, fallback = 0;
  for (const Material& m : cases)
    for (const Vec3& ns : {kUp, tilted}) {
      const Bsdf bsdf(m, ns, kUp);
      const float p_lobe = bsdf.RouletteProbability(kUp, kLobeAll);  // one lobe: its mean
      for (int i = 0; i < 20000; ++i) {
        const Vec3 wo = UniformSphere(rng);
        const auto s =
            bsdf.Sample(wo, rng.Uniform(), rng.Uniform(), rng.Uniform(), Bsdf::Mode::kRussianRoulette);
        if (!s) continue;
        const float pdf = p_lobe * bsdf.Pdf(wo, s->wi);
        const Rgb f = bsdf.Eval(wo, s->wi);
        ASSERT_GT(pdf, 0.0f);
        EXPECT_NEAR(s->pdf, pdf, 1e-4f * pdf);
        for (int ch = 0; ch < 3; ++ch) {
          const float expected = f[ch] * bsdf.AbsCosTheta(s->wi) / pdf;
          ASSERT_NEAR(s->weight[ch], expected, 1e-4f * expected);
        }
        fallback += Dot(wo, ns) * Dot(wo, kUp) < 0.0f;
        ++checked;
      }
    }
  EXPECT_GT(checked, 40000);
  EXPECT_GT(fallback, 1000);  // the EvalPdf fallback was exercised

  // Several lobes (diffuse reflection and transmission beside a glossy one), shading normal
  // upright and tilted: a diffuse sample's weight is its own lobe's ρ over its own selection
  // probability, the channel mean of that ρ (§2.2) — not over the total survival probability.
  Material mixed = Glossy(0.3f, 0.2f);
  mixed.diffuse_reflectance = Rgb(0.5f, 0.3f, 0.2f);
  mixed.diffuse_transmittance = Rgb(0.1f, 0.2f, 0.05f);
  int diffuse_checked = 0;
  for (const Vec3& ns : {kUp, tilted}) {
    const Bsdf bsdf(mixed, ns, kUp);
    for (int i = 0; i < 20000; ++i) {
      const Vec3 wo = UniformSphere(rng);
      if (Dot(wo, ns) * Dot(wo, kUp) <= 0.0f) continue;  // the fallback: checked above
      const auto s =
          bsdf.Sample(wo, rng.Uniform(), rng.Uniform(), rng.Uniform(), Bsdf::Mode::kRussianRoulette);
      if (!s) continue;
      const Rgb* rho = s->lobe == kLobeDiffuseReflection     ? &mixed.diffuse_reflectance
                       : s->lobe == kLobeDiffuseTransmission ? &mixed.diffuse_transmittance
                                                             : nullptr;
      if (rho == nullptr) continue;
      for (int ch = 0; ch < 3; ++ch) {
        const float expected = (*rho)[ch] / rho->Mean();
        ASSERT_NEAR(s->weight[ch], expected, 1e-4f * expected) << "lobe " << s->lobe << " channel " << ch;
      }
      ++diffuse_checked;
    }
  }
  EXPECT_GT(diffuse_checked, 8000);
}

// ---------------------------------------------------------------------------------------------

TEST(BsdfRussianRoulette, SurvivalIsSumOfMeansAndWeightIsUnbiased) {
  Material m = Glossy(0.2f, 0.3f);
  m.specular_reflectance = Rgb(0.2f, 0.3f, 0.1f);
  m.diffuse_reflectance = Rgb(0.6f, 0.3f, 0.1f);
  m.diffuse_transmittance = Rgb(0.1f, 0.05f, 0.2f);
  m.specular_transmittance = Rgb(0.05f);  // thin
  const Bsdf bsdf(m, kUp, kUp);
  const double survival = m.diffuse_reflectance.Mean() + m.specular_reflectance.Mean() +
                          m.diffuse_transmittance.Mean() + m.specular_transmittance.Mean();
  // wo = n: the glossy albedo is ρs·(1 − α²(1 − e^(−1/α²))) (see BsdfEnergy).
  const double a2 = 0.09, glossy_albedo = 1.0 - a2 * (1.0 - std::exp(-1.0 / a2));
  const int n = 200'000;
  const Albedo rr = EstimateAlbedo(bsdf, kUp, n, 8, Bsdf::Mode::kRussianRoulette);
  const Albedo norm = EstimateAlbedo(bsdf, kUp, n, 9, Bsdf::Mode::kNormalized);
  std::printf("[roulette] survival %.5f (expected %.5f)\n", rr.survival, survival);
  EXPECT_NEAR(rr.survival, survival, 4 * std::sqrt(survival * (1 - survival) / n));
  for (int ch = 0; ch < 3; ++ch) {
    const double albedo = m.diffuse_reflectance[ch] + m.specular_reflectance[ch] * glossy_albedo +
                          m.diffuse_transmittance[ch] + m.specular_transmittance[ch];
    std::printf("[roulette] ch %d albedo %.5f: RR %.5f ± %.5f, normalized %.5f ± %.5f\n", ch, albedo,
                rr.mean[ch], rr.sigma[ch], norm.mean[ch], norm.sigma[ch]);
    EXPECT_NEAR(rr.mean[ch], albedo, 4 * rr.sigma[ch] + 1e-5) << "channel " << ch;
    EXPECT_NEAR(norm.mean[ch], albedo, 4 * norm.sigma[ch] + 1e-5) << "channel " << ch;
  }
  // The diffuse lobe's weight is exactly the thesis's ρ/P per channel.
  Rng rng(3, 3);
  for (int i = 0; i < 1000; ++i) {
    const auto s =
        bsdf.Sample(FromCos(0.6f), rng.Uniform(), rng.Uniform(), rng.Uniform(), Bsdf::Mode::kRussianRoulette);
    if (!s || s->lobe != kLobeDiffuseReflection) continue;
    for (int ch = 0; ch < 3; ++ch) {
      EXPECT_NEAR(s->weight[ch], m.diffuse_reflectance[ch] / m.diffuse_reflectance.Mean(), 1e-4f);
    }
  }
}

TEST(BsdfRussianRoulette, MeansAboveOneAreClampedAndNeverAbsorb) {
  Material m = Glossy(0.5f, 0.0f);  // mirror
  m.diffuse_reflectance = Rgb(0.9f);
  const Bsdf bsdf(m, kUp, kUp);
  const int n = 100'000;
  const Albedo rr = EstimateAlbedo(bsdf, FromCos(0.5f), n, 4, Bsdf::Mode::kRussianRoulette);
  EXPECT_EQ(rr.survival, 1.0);
  EXPECT_NEAR(rr.mean[0], 1.4, 4 * rr.sigma[0] + 1e-5);
}

TEST(BsdfRussianRoulette, DielectricSurvivesWithItsAlbedo) {
  const Material m = Dielectric(0.5f, 1.5f);
  const Rgb tau(0.8f, 0.5f, 0.2f);
  Material tinted = m;
  tinted.specular_transmittance = tau;
  const Bsdf bsdf(tinted, kUp, kUp);
  const float c = 0.3f;
  const double f = FresnelDielectric(c, 1.5f);
  const int n = 200'000;
  const Albedo rr = EstimateAlbedo(bsdf, FromCos(c), n, 6, Bsdf::Mode::kRussianRoulette);
  const double survival = f + (1 - f) * tau.Mean();
  EXPECT_NEAR(rr.survival, survival, 4 * std::sqrt(survival * (1 - survival) / n));
  for (int ch = 0; ch < 3; ++ch) {
    EXPECT_NEAR(rr.mean[ch], f + (1 - f) * tau[ch], 4 * rr.sigma[ch] + 1e-5) << "channel " << ch;
  }
}

// ---------------------------------------------------------------------------------------------
// Lobe-restricted sampling (the photon map shader traces singular lobes, estimates diffuse ones).

TEST(BsdfLobeMask, HasLobes) {
  const Bsdf diffuse(Diffuse(0.5f), kUp, kUp);
  EXPECT_TRUE(diffuse.HasLobes(kLobeDiffuseReflection));
  EXPECT_FALSE(diffuse.HasLobes(kLobeGlossyReflection | kLobeSpecularTransmission));
  const Bsdf mirror(Glossy(0.5f, 0.0f), kUp, kUp);
  EXPECT_TRUE(mirror.HasLobes(kLobeSpecularReflection));
  EXPECT_FALSE(mirror.HasLobes(kLobeGlossyReflection));
  const Bsdf glossy(Glossy(0.5f, 0.1f), kUp, kUp);
  EXPECT_TRUE(glossy.HasLobes(kLobeGlossyReflection));
  EXPECT_FALSE(glossy.HasLobes(kLobeSpecularReflection));
  Material glass = Dielectric(0.9f, 1.5f);
  glass.diffuse_reflectance = Rgb(0.5f);  // ignored
  const Bsdf dielectric(glass, kUp, kUp);
  EXPECT_TRUE(dielectric.HasLobes(kLobeSpecularReflection));
  EXPECT_TRUE(dielectric.HasLobes(kLobeSpecularTransmission));
  EXPECT_FALSE(dielectric.HasLobes(kLobeDiffuseReflection | kLobeDiffuseTransmission));
  EXPECT_FALSE(Bsdf(Material{}, kUp, kUp).HasLobes(kLobeAll));
}

TEST(BsdfLobeMask, RestrictedSamplingEstimatesTheAllowedLobesAlbedo) {
  Material m = Glossy(0.3f, 0.2f);
  m.diffuse_reflectance = Rgb(0.5f, 0.4f, 0.3f);
  m.specular_transmittance = Rgb(0.1f);  // thin
  const Bsdf bsdf(m, kUp, kUp);
  const double a2 = 0.04, glossy_albedo = 1.0 - a2 * (1.0 - std::exp(-1.0 / a2));
  const uint32_t singular = kLobeGlossyReflection | kLobeSpecularReflection | kLobeSpecularTransmission;
  const int n = 200'000;
  for (auto mode : {Bsdf::Mode::kNormalized, Bsdf::Mode::kRussianRoulette}) {
    Rng rng(12, 1);
    double sum = 0, sum2 = 0;
    int survived = 0;
    for (int i = 0; i < n; ++i) {
      const auto s = bsdf.Sample(kUp, rng.Uniform(), rng.Uniform(), rng.Uniform(), mode, singular);
      if (!s) continue;
      ++survived;
      ASSERT_NE(s->lobe & singular, 0u);
      if (!s->is_delta && mode == Bsdf::Mode::kNormalized) {
        const float expected = bsdf.EvalLobes(kUp, s->wi, singular).r * bsdf.AbsCosTheta(s->wi) / s->pdf;
        ASSERT_NEAR(s->weight.r, expected, 1e-4f * expected);
      }
      sum += s->weight.r;
      sum2 += double(s->weight.r) * s->weight.r;
    }
    const double mean = sum / n, sigma = std::sqrt((sum2 / n - mean * mean) / n);
    EXPECT_NEAR(mean, 0.3 * glossy_albedo + 0.1, 4 * sigma + 1e-5);
    if (mode == Bsdf::Mode::kRussianRoulette) {
      EXPECT_NEAR(double(survived) / n, 0.4, 4 * std::sqrt(0.24 / n));  // ρs + τs means
    } else {
      EXPECT_EQ(survived, n);  // at normal incidence a glossy sample is lost w.p. e^(−1/α²) ≈ 1e-11
    }
  }
  // Diffuse only: weight exactly ρd (renormalised selection).
  Rng rng(13, 1);
  for (int i = 0; i < 1000; ++i) {
    const auto s = bsdf.Sample(FromCos(0.4f), rng.Uniform(), rng.Uniform(), rng.Uniform(),
                               Bsdf::Mode::kNormalized, kLobeDiffuseReflection);
    ASSERT_TRUE(s.has_value());
    EXPECT_EQ(s->lobe, kLobeDiffuseReflection);
    for (int ch = 0; ch < 3; ++ch) EXPECT_NEAR(s->weight[ch], m.diffuse_reflectance[ch], 1e-5f);
  }
  // The unrestricted overload is the full mask.
  const auto a = bsdf.Sample(FromCos(0.4f), 0.3f, 0.2f, 0.7f);
  const auto b = bsdf.Sample(FromCos(0.4f), 0.3f, 0.2f, 0.7f, Bsdf::Mode::kNormalized, kLobeAll);
  ASSERT_TRUE(a && b);
  EXPECT_EQ(a->wi, b->wi);
  EXPECT_EQ(a->weight, b->weight);
}

TEST(BsdfLobeMask, DielectricBranchesCanBeRestricted) {
  const Rgb tau(0.9f, 0.8f, 0.7f);
  Material glass = Dielectric(1.0f, 1.5f);
  glass.specular_transmittance = tau;
  const Bsdf bsdf(glass, kUp, kUp);
  const Vec3 wo = FromCos(0.6f);
  const float f = FresnelDielectric(0.6f, 1.5f);
  for (float u : {0.0f, 0.5f, 0.999f}) {
    const auto r = bsdf.Sample(wo, u, 0.5f, 0.5f, Bsdf::Mode::kNormalized, kLobeSpecularReflection);
    ASSERT_TRUE(r.has_value());
    EXPECT_EQ(r->lobe, kLobeSpecularReflection);
    EXPECT_NEAR(r->weight.g, f, 1e-6f);
    const auto t = bsdf.Sample(wo, u, 0.5f, 0.5f, Bsdf::Mode::kNormalized, kLobeSpecularTransmission);
    ASSERT_TRUE(t.has_value());
    EXPECT_EQ(t->lobe, kLobeSpecularTransmission);
    EXPECT_NEAR(t->weight.g, (1 - f) * tau.g, 1e-6f);
  }
  // Total internal reflection with refraction alone allowed: nothing.
  const Vec3 inside = Spherical((180.0 - 60.0) * kPiD / 180, 0.0);
  EXPECT_FALSE(
      bsdf.Sample(inside, 0.5f, 0.5f, 0.5f, Bsdf::Mode::kNormalized, kLobeSpecularTransmission).has_value());
  EXPECT_FALSE(
      bsdf.Sample(wo, 0.5f, 0.5f, 0.5f, Bsdf::Mode::kNormalized, kLobeDiffuseReflection).has_value());
}

// ---------------------------------------------------------------------------------------------

TEST(Fresnel, NormalIncidence) {
  for (float eta : {1.5f, 1.0f / 1.5f, 2.4f, 1.33f}) {
    const float r0 = (eta - 1) / (eta + 1);
    EXPECT_NEAR(FresnelDielectric(1.0f, eta), r0 * r0, 1e-6f) << eta;
  }
  EXPECT_EQ(FresnelDielectric(0.7f, 1.0f), 0.0f);
}

TEST(Fresnel, MatchesTheAngleForm) {
  // Rs = sin²(θi−θt)/sin²(θi+θt), Rp = tan²(θi−θt)/tan²(θi+θt), an independent formulation.
  for (double eta : {1.5, 1.0 / 1.5, 2.4}) {
    for (double ti = 0.05; ti < 1.5; ti += 0.1) {
      const double st = std::sin(ti) / eta;
      if (st >= 1) continue;
      const double tt = std::asin(st);
      const double rs = std::pow(std::sin(ti - tt) / std::sin(ti + tt), 2);
      const double rp = std::pow(std::tan(ti - tt) / std::tan(ti + tt), 2);
      EXPECT_NEAR(FresnelDielectric(float(std::cos(ti)), float(eta)), 0.5 * (rs + rp), 2e-5)
          << "eta " << eta << " θi " << ti;
    }
  }
}

TEST(Fresnel, TotalInternalReflectionAndGrazing) {
  const float eta = 1.0f / 1.5f;  // glass → air
  const float critical = std::asin(eta);
  EXPECT_EQ(FresnelDielectric(std::cos(critical + 0.01f), eta), 1.0f);
  EXPECT_EQ(FresnelDielectric(std::cos(1.2f), eta), 1.0f);
  EXPECT_LT(FresnelDielectric(std::cos(critical - 0.05f), eta), 1.0f);
  EXPECT_GT(FresnelDielectric(1e-4f, 1.5f), 0.999f);
  EXPECT_EQ(FresnelDielectric(0.0f, 1.5f), 1.0f);
  EXPECT_GT(FresnelDielectric(0.01f, 1.5f), FresnelDielectric(0.3f, 1.5f));
}

TEST(Fresnel, SymmetricUnderReversal) {
  // F(θi, η) == F(θt, 1/η): the same interface seen from either side.
  for (float eta : {1.5f, 2.0f, 1.1f}) {
    for (float ci = 0.02f; ci <= 1.0f; ci += 0.07f) {
      const float ct = std::sqrt(1.0f - (1.0f - ci * ci) / (eta * eta));
      EXPECT_NEAR(FresnelDielectric(ci, eta), FresnelDielectric(ct, 1.0f / eta), 1e-5f) << eta << " " << ci;
    }
  }
}

// ---------------------------------------------------------------------------------------------

TEST(BsdfSidedness, ReflectionFromTheBackSide) {
  Material m = Glossy(0.5f, 0.2f);
  m.diffuse_reflectance = Rgb(0.5f);
  const Bsdf bsdf(m, kUp, kUp);
  const Vec3 wo = FromCos(-0.6f);
  Rng rng(1, 1);
  for (int i = 0; i < 2000; ++i) {
    const auto s = bsdf.Sample(wo, rng.Uniform(), rng.Uniform(), rng.Uniform());
    if (!s) continue;
    EXPECT_LT(s->wi.z, 0.0f);
  }
  // Mirror image through the surface plane: the same values from the front.
  auto flip = [](Vec3 v) { return Vec3(v.x, v.y, -v.z); };
  for (int i = 0; i < 2000; ++i) {
    const Vec3 a = UniformSphere(rng), b = UniformSphere(rng);
    const Rgb fa = bsdf.Eval(a, b), fb = bsdf.Eval(flip(a), flip(b));
    EXPECT_NEAR(fa.r, fb.r, 1e-5f * std::max(1.0f, fa.r));
    EXPECT_NEAR(bsdf.Pdf(a, b), bsdf.Pdf(flip(a), flip(b)), 1e-5f * std::max(1.0f, bsdf.Pdf(a, b)));
  }
  EXPECT_NEAR(bsdf.Eval(wo, FromCos(-0.5f, 2.5f)).r, 0.5f * kInvPi, 1e-3f);  // diffuse part
  EXPECT_TRUE(bsdf.Eval(wo, FromCos(0.5f, 2.5f)).IsBlack());                 // other side
  EXPECT_EQ(bsdf.Pdf(wo, FromCos(0.5f, 2.5f)), 0.0f);
}

TEST(BsdfSidedness, DiffuseTransmissionGoesToTheOtherSide) {
  Material m;
  m.diffuse_transmittance = Rgb(0.6f);
  const Bsdf bsdf(m, kUp, kUp);
  Rng rng(2, 2);
  for (float side : {1.0f, -1.0f}) {
    const Vec3 wo = FromCos(side * 0.4f);
    for (int i = 0; i < 1000; ++i) {
      const auto s = bsdf.Sample(wo, rng.Uniform(), rng.Uniform(), rng.Uniform());
      ASSERT_TRUE(s.has_value());
      EXPECT_LT(s->wi.z * side, 0.0f);
      EXPECT_EQ(s->lobe, kLobeDiffuseTransmission);
    }
    EXPECT_TRUE(bsdf.Eval(wo, FromCos(side * 0.5f)).IsBlack());
    EXPECT_NEAR(bsdf.Eval(wo, FromCos(-side * 0.5f)).r, 0.6f * kInvPi, 1e-6f);
  }
}

TEST(BsdfSidedness, DielectricEntersWithEtaAndExitsWithInverse) {
  const float ior = 1.5f;
  const Bsdf bsdf(Dielectric(1.0f, ior), kUp, kUp);
  auto sin_theta = [](const Vec3& v) { return std::sqrt(v.x * v.x + v.y * v.y); };
  // Entering from the front at 50°: sinθt = sinθo / 1.5, below the surface, continuing forward.
  {
    const Vec3 wo = Spherical(50.0 * kPiD / 180, 0.7);
    const auto s = bsdf.Sample(wo, 0.9999f, 0.5f, 0.5f);
    ASSERT_TRUE(s.has_value());
    EXPECT_EQ(s->lobe, kLobeSpecularTransmission);
    EXPECT_LT(s->wi.z, 0.0f);
    EXPECT_NEAR(sin_theta(s->wi), sin_theta(wo) / ior, 1e-5f);
    EXPECT_LT(s->wi.x * wo.x + s->wi.y * wo.y, 0.0f);  // tangential part reversed w.r.t. wo
    EXPECT_NEAR(Length(s->wi), 1.0f, 1e-5f);
  }
  // Exiting from the back at 30°: sinθt = 1.5·sinθo.
  {
    const Vec3 wo = Spherical((180.0 - 30.0) * kPiD / 180, 2.0);
    const auto s = bsdf.Sample(wo, 0.9999f, 0.5f, 0.5f);
    ASSERT_TRUE(s.has_value());
    EXPECT_EQ(s->lobe, kLobeSpecularTransmission);
    EXPECT_GT(s->wi.z, 0.0f);
    EXPECT_NEAR(sin_theta(s->wi), sin_theta(wo) * ior, 1e-5f);
  }
  // From the back at 45° (> critical 41.8°): total internal reflection for every u_lobe.
  {
    const Vec3 wo = Spherical((180.0 - 45.0) * kPiD / 180, 1.0);
    for (float u : {0.0f, 0.5f, 0.99999f}) {
      const auto s = bsdf.Sample(wo, u, 0.5f, 0.5f);
      ASSERT_TRUE(s.has_value());
      EXPECT_EQ(s->lobe, kLobeSpecularReflection);
      EXPECT_LT(s->wi.z, 0.0f);
      EXPECT_NEAR(s->wi.z, wo.z, 1e-6f);
      EXPECT_EQ(s->weight, Rgb(1.0f));
    }
  }
  // Reflection branch: mirror direction, weight 1 even for a tinted τs.
  {
    Material tinted = Dielectric(1.0f, ior);
    tinted.specular_transmittance = Rgb(0.2f, 0.5f, 0.9f);
    tinted.diffuse_reflectance = Rgb(0.5f);  // ignored for a dielectric
    const Bsdf b(tinted, kUp, kUp);
    EXPECT_FALSE(b.HasDiffuse());
    EXPECT_FALSE(b.HasNonDelta());
    const Vec3 wo = FromCos(0.5f);
    EXPECT_TRUE(b.Eval(wo, FromCos(0.5f, 2.0f)).IsBlack());
    const auto r = b.Sample(wo, 0.0f, 0.5f, 0.5f);
    ASSERT_TRUE(r.has_value());
    EXPECT_EQ(r->lobe, kLobeSpecularReflection);
    EXPECT_EQ(r->weight, Rgb(1.0f));
    const auto t = b.Sample(wo, 0.9999f, 0.5f, 0.5f);
    ASSERT_TRUE(t.has_value());
    EXPECT_EQ(t->weight, tinted.specular_transmittance);
  }
}

TEST(BsdfSidedness, ShadingNormalSamplesBelowTheGeometricSurfaceAreRejected) {
  // ns tilted 40° towards +x; wo at 80° from ns on the −x side: the mirror direction about ns
  // points 120° away from ng, i.e. under the surface.
  const Vec3 ns(std::sin(0.698f), 0.0f, std::cos(0.698f));
  const Vec3 wo(-std::sin(0.698f), 0.0f, std::cos(0.698f));
  const Bsdf mirror(Glossy(1.0f, 0.0f), ns, kUp);
  EXPECT_FALSE(mirror.Sample(wo, 0.5f, 0.5f, 0.5f).has_value());
  // wo below the shading hemisphere (wo·ns < 0): the lobes fall back to ng, so the mirror
  // reflects about ng instead of sending everything under the surface.
  const Vec3 low(-std::sin(1.047f), 0.0f, std::cos(1.047f));
  ASSERT_LT(Dot(low, ns), 0.0f);
  const auto fallback = mirror.Sample(low, 0.5f, 0.5f, 0.5f);
  ASSERT_TRUE(fallback.has_value());
  EXPECT_NEAR(fallback->wi.x, -low.x, 1e-6f);
  EXPECT_NEAR(fallback->wi.z, low.z, 1e-6f);
  // A thin straight-through sample is always on the other side; a reflection to the other side
  // of ng is never evaluated.
  const Bsdf diffuse(Diffuse(1.0f), ns, kUp);
  EXPECT_TRUE(diffuse.Eval(wo, -kUp).IsBlack());
  EXPECT_EQ(diffuse.Pdf(wo, -kUp), 0.0f);
  // Shading normals given on the wrong side are flipped into ng's hemisphere.
  const Bsdf flipped(Diffuse(1.0f), -ns, kUp);
  EXPECT_GT(Dot(flipped.shading_normal(), kUp), 0.0f);
}

// ---------------------------------------------------------------------------------------------

TEST(BsdfRobustness, ClassificationAndDegenerateMaterials) {
  EXPECT_TRUE(Bsdf(Diffuse(0.5f), kUp, kUp).HasDiffuse());
  EXPECT_TRUE(Bsdf(Glossy(0.5f, 0.2f), kUp, kUp).HasNonDelta());
  EXPECT_FALSE(Bsdf(Glossy(0.5f, 0.2f), kUp, kUp).HasDiffuse());
  EXPECT_FALSE(Bsdf(Glossy(0.5f, 0.0f), kUp, kUp).HasNonDelta());
  // α below 1e-4 is a mirror.
  const auto s = Bsdf(Glossy(0.5f, 1e-5f), kUp, kUp).Sample(FromCos(0.5f), 0.1f, 0.3f, 0.3f);
  ASSERT_TRUE(s.has_value());
  EXPECT_TRUE(s->is_delta);
  EXPECT_EQ(s->lobe, kLobeSpecularReflection);
  EXPECT_TRUE(IsSingular(s->lobe));
  // transmission_roughness > 0 is still perfect transmission.
  Material rough = Dielectric(1.0f, 1.0f);
  rough.transmission_roughness = 0.3f;
  const auto t = Bsdf(rough, kUp, kUp).Sample(FromCos(0.5f), 0.5f, 0.3f, 0.3f);
  ASSERT_TRUE(t.has_value());
  EXPECT_TRUE(t->is_delta);
  EXPECT_EQ(t->wi, -FromCos(0.5f));
  // Black material: nothing.
  EXPECT_FALSE(Bsdf(Material{}, kUp, kUp).Sample(FromCos(0.5f), 0.5f, 0.5f, 0.5f).has_value());
  // wo in the surface plane: zero everywhere.
  const Bsdf d(Diffuse(0.5f), kUp, kUp);
  EXPECT_FALSE(d.Sample(Vec3(1, 0, 0), 0.5f, 0.5f, 0.5f).has_value());
  EXPECT_TRUE(d.Eval(Vec3(1, 0, 0), kUp).IsBlack());
  EXPECT_EQ(d.Pdf(Vec3(1, 0, 0), kUp), 0.0f);
}

TEST(BsdfRobustness, NeverProducesNanOrInf) {
  Rng rng(77, 1);
  const float alphas[] = {0.0f, 1e-5f, 1e-4f, 1e-3f, 0.05f, 1.0f, 3.0f};
  const float iors[] = {1.0f, 1.00005f, 1.5f, 0.5f, 0.0f, -1.0f};
  const float edge_u[] = {0.0f, 0.5f, 1.0f - 0x1p-24f};
  for (int i = 0; i < 100'000; ++i) {
    Material m;
    m.diffuse_reflectance = Rgb(rng.Uniform() < 0.5f ? 0.0f : rng.Uniform());
    m.specular_reflectance = Rgb(rng.Uniform() < 0.5f ? 0.0f : rng.Uniform(), 0.3f, 0.0f);
    m.specular_roughness = alphas[rng.UniformInt(7)];
    m.diffuse_transmittance = Rgb(rng.Uniform() < 0.7f ? 0.0f : rng.Uniform());
    m.specular_transmittance = Rgb(rng.Uniform() < 0.6f ? 0.0f : rng.Uniform());
    m.ior = iors[rng.UniformInt(6)];
    const Vec3 ng = UniformSphere(rng);
    Vec3 ns = rng.Uniform() < 0.3f ? ng : Normalize(ng + UniformSphere(rng) * 1.5f);
    if (i % 97 == 0) ns = Vec3(0.0f);
    if (i % 89 == 0) ns = Normalize(Cross(ng, Vec3(0.3f, 0.5f, 0.8f)));  // perpendicular
    Vec3 wo = UniformSphere(rng);
    if (i % 13 == 0) wo = Normalize(wo - ng * Dot(wo, ng));                  // (nearly) in the plane
    if (i % 17 == 0) wo = Normalize(ng * 1e-4f + Normalize(Cross(ng, wo)));  // grazing
    const Bsdf bsdf(m, ns, ng);
    const float ul = i % 5 == 0 ? edge_u[rng.UniformInt(3)] : rng.Uniform();
    const float u1 = i % 7 == 0 ? edge_u[rng.UniformInt(3)] : rng.Uniform();
    const float u2 = rng.Uniform();
    for (auto mode : {Bsdf::Mode::kNormalized, Bsdf::Mode::kRussianRoulette}) {
      const auto s = bsdf.Sample(wo, ul, u1, u2, mode);
      if (!s) continue;
      ASSERT_TRUE(s->weight.IsFinite()) << i;
      ASSERT_TRUE(IsFinite(s->wi)) << i;
      ASSERT_TRUE(std::isfinite(s->pdf) && s->pdf > 0.0f) << i;
      ASSERT_GE(std::min({s->weight.r, s->weight.g, s->weight.b}), 0.0f) << i;
      ASSERT_NEAR(Length(s->wi), 1.0f, 1e-3f) << i;
    }
    const Vec3 wi = UniformSphere(rng);
    ASSERT_TRUE(bsdf.Eval(wo, wi).IsFinite()) << i;
    ASSERT_TRUE(std::isfinite(bsdf.Pdf(wo, wi))) << i;
    ASSERT_TRUE(bsdf.Eval(wo, -wo).IsFinite()) << i;
    ASSERT_TRUE(std::isfinite(bsdf.Pdf(wo, wo))) << i;
  }
}

bool SameBits(const Vec3& a, const Vec3& b) {
  return std::bit_cast<uint32_t>(a.x) == std::bit_cast<uint32_t>(b.x) &&
         std::bit_cast<uint32_t>(a.y) == std::bit_cast<uint32_t>(b.y) &&
         std::bit_cast<uint32_t>(a.z) == std::bit_cast<uint32_t>(b.z);
}

TEST(BsdfShadingNormal, FollowsTheNormalisationRuleBitForBit) {
  // The constructor skips normalising ns when it is ng itself (flat triangles). The shading
  // normal must still be exactly what the rule gives: Normalize(ns), flipped into ng's
  // hemisphere, unless (nearly) in the surface plane. ns equal to ng but for the sign of a zero
  // component is the trap: == holds, yet Frame's copysign tells the two apart.
  Rng rng(7, 3);
  std::vector<std::pair<Vec3, Vec3>> cases;  // (ns, ng)
  cases.push_back({Vec3(-0.0f, 0.6f, 0.8f), Vec3(0.0f, 0.6f, 0.8f)});
  cases.push_back({Vec3(0.0f, -0.0f, 1.0f), Vec3(0.0f, 0.0f, 1.0f)});
  cases.push_back({Vec3(0.0f, 0.0f, -1.0f), Vec3(-0.0f, 0.0f, -1.0f)});
  for (int i = 0; i < 2000; ++i) {
    const Vec3 ng = UniformSphere(rng) * (0.5f + rng.Uniform());  // not unit: the constructor normalises
    cases.push_back({ng, ng});
    cases.push_back({UniformSphere(rng), ng});
    cases.push_back({-ng, ng});
  }
  for (const auto& [ns, ng] : cases) {
    const Vec3 g = Normalize(ng);
    Vec3 n = Normalize(ns);
    if (Dot(n, g) < 0.0f) n = -n;
    const Vec3 expected = Dot(n, g) > 1e-3f ? n : g;
    const Bsdf b(Diffuse(0.5f), ns, ng);
    EXPECT_TRUE(SameBits(b.shading_normal(), expected))
        << ns.x << " " << ns.y << " " << ns.z << " / " << ng.x << " " << ng.y << " " << ng.z;
    EXPECT_TRUE(SameBits(b.geometric_normal(), g));
  }
}

TEST(BsdfLobes, PrecomputedLobesGiveTheSameSamples) {
  // The photon tracer builds its Bsdfs from BsdfLobes computed once per material: every sample,
  // value and pdf must equal the plain constructor's, for every kind of material.
  Material thin;
  thin.specular_transmittance = Rgb(0.7f, 0.5f, 0.3f);
  Material glass;
  glass.specular_transmittance = Rgb(0.9f);
  glass.ior = 1.5f;
  Material bright;  // means summing past 1: the roulette probabilities are rescaled
  bright.diffuse_reflectance = Rgb(0.8f);
  bright.specular_reflectance = Rgb(0.6f);
  bright.specular_roughness = 0.2f;
  Material nan_roughness = Glossy(0.5f, std::nanf(""));
  const std::vector<Material> materials = {Diffuse(0.5f), Glossy(0.4f, 0.1f), Glossy(0.9f, 0.0f), thin, glass,
                                           bright,        nan_roughness,      Material{}};
  Rng rng(11, 5);
  for (const Material& m : materials) {
    const BsdfLobes lobes = BsdfLobes::Of(m);
    for (int i = 0; i < 500; ++i) {
      const Vec3 ng = UniformSphere(rng), ns = i % 2 ? ng : UniformSphere(rng);
      const Vec3 wo = UniformSphere(rng), wi = UniformSphere(rng);
      const Bsdf a(m, ns, ng), b(m, lobes, ns, ng);
      EXPECT_EQ(a.Eval(wo, wi), b.Eval(wo, wi));
      EXPECT_EQ(a.Pdf(wo, wi), b.Pdf(wo, wi));
      EXPECT_EQ(a.HasDiffuse(), b.HasDiffuse());
      const float ul = rng.Uniform(), u1 = rng.Uniform(), u2 = rng.Uniform();
      for (Bsdf::Mode mode : {Bsdf::Mode::kNormalized, Bsdf::Mode::kRussianRoulette}) {
        const std::optional<BsdfSample> sa = a.Sample(wo, ul, u1, u2, mode),
                                        sb = b.Sample(wo, ul, u1, u2, mode);
        ASSERT_EQ(sa.has_value(), sb.has_value());
        if (!sa) continue;
        EXPECT_TRUE(SameBits(sa->wi, sb->wi));
        EXPECT_EQ(sa->weight, sb->weight);
        EXPECT_EQ(sa->pdf, sb->pdf);
        EXPECT_EQ(sa->lobe, sb->lobe);
      }
    }
  }
}

// The photon walk's roulette shortcut (WalkRoulette, bsdf.h) must be Bsdf::Sample in
// kRussianRoulette wherever it answers: kAbsorbed only where Sample returns nullopt, kDiffuse only
// where Sample picks diffuse reflection, with the same wi and weight bit for bit (the photon maps
// must not change). Every kind of material; unit, axis-aligned (squared length exactly 1),
// unnormalised, zero and NaN normals; wo on both sides and in the plane; flat and smooth hits.
// And it must answer often enough to matter: on a plain diffuse material most bounces.
TEST(BsdfWalkRoulette, AgreesWithSampleBitForBit) {
  Material coloured = Diffuse(0.5f);
  coloured.diffuse_reflectance = Rgb(0.8f, 0.3f, 0.1f);
  Material translucent = Diffuse(0.4f);
  translucent.diffuse_transmittance = Rgb(0.3f);
  Material glass;
  glass.specular_transmittance = Rgb(0.9f);
  glass.ior = 1.5f;
  Material bright;  // means summing past 1: the roulette probabilities are rescaled, nothing absorbs
  bright.diffuse_reflectance = Rgb(0.8f);
  bright.specular_reflectance = Rgb(0.6f);
  bright.specular_roughness = 0.2f;
  const std::vector<Material> materials = {Diffuse(0.5f),      coloured, translucent, Glossy(0.4f, 0.1f),
                                           Glossy(0.9f, 0.0f), glass,    bright,      Material{}};
  Rng rng(23, 7);
  for (size_t mi = 0; mi < materials.size(); ++mi) {
    const Material& m = materials[mi];
    const BsdfLobes lobes = BsdfLobes::Of(m);
    const WalkRoulette roulette = WalkRoulette::Of(m, lobes);
    int counts[3] = {};
    for (int i = 0; i < 20000; ++i) {
      Vec3 ng = UniformSphere(rng);
      switch (i % 10) {
        case 0:
          ng = Vec3(0.0f, i % 20 ? 1.0f : -1.0f, 0.0f);
          break;  // exactly unit
        case 1:
          ng = ng * 3.0f;
          break;  // not unit
        case 2:
          if (i % 1000 == 2) ng = Vec3(0.0f);
          break;  // unusable
        case 3:
          if (i % 1000 == 3) ng = Vec3(std::nanf(""), 0.0f, 1.0f);
          break;
        default:
          break;
      }
      const bool flat = i % 7 != 0;
      const Vec3 ns = flat ? ng : UniformSphere(rng);
      Vec3 wo = UniformSphere(rng);
      if (i % 97 == 0) wo = Normalize(Cross(ng, Vec3(0.3f, 0.5f, 0.8f)));  // in the surface plane
      const float ul = rng.Uniform(), u1 = rng.Uniform(), u2 = rng.Uniform();
      const Bsdf bsdf(m, lobes, ns, ng);
      EXPECT_EQ(roulette.Stores(ng), bsdf.HasDiffuse()) << "material " << mi;
      Vec3 wi;
      const WalkRoulette::Outcome outcome = roulette.At(ng, flat, wo, ul, u1, u2, &wi);
      ++counts[int(outcome)];
      if (outcome == WalkRoulette::Outcome::kBsdf) continue;
      const std::optional<BsdfSample> s = bsdf.Sample(wo, ul, u1, u2, Bsdf::Mode::kRussianRoulette);
      if (outcome == WalkRoulette::Outcome::kAbsorbed) {
        EXPECT_FALSE(s.has_value()) << "material " << mi << " sample " << i;
        continue;
      }
      ASSERT_TRUE(s.has_value()) << "material " << mi << " sample " << i;
      EXPECT_EQ(s->lobe, kLobeDiffuseReflection);
      EXPECT_TRUE(SameBits(s->wi, wi)) << "material " << mi << " sample " << i;
      EXPECT_EQ(std::bit_cast<uint32_t>(s->weight.r), std::bit_cast<uint32_t>(roulette.diffuse_weight.r));
      EXPECT_EQ(std::bit_cast<uint32_t>(s->weight.g), std::bit_cast<uint32_t>(roulette.diffuse_weight.g));
      EXPECT_EQ(std::bit_cast<uint32_t>(s->weight.b), std::bit_cast<uint32_t>(roulette.diffuse_weight.b));
    }
    if (mi == 0) {
      // Plain diffuse, ρ = 0.5: about half the bounces absorbed, most of the rest diffuse here.
      EXPECT_GT(counts[int(WalkRoulette::Outcome::kAbsorbed)], 8000);
      EXPECT_GT(counts[int(WalkRoulette::Outcome::kDiffuse)], 6000);
    }
    if (mi == 5) {
      EXPECT_EQ(counts[int(WalkRoulette::Outcome::kBsdf)], 20000);  // glass: always the Bsdf
    }
  }
}

// RouletteProbability (Metropolis caustic splitting's acceptance ratio, Wald 1999, §4.6.2) is the
// frequency with which Sample in kRussianRoulette picks a lobe of the mask: for a dielectric at
// several angles from both sides (Fresnel), and for a mix of diffuse, mirror and thin
// transmission, within 4 binomial standard deviations of 200k uniform lobe numbers.
TEST(BsdfRussianRoulette, RouletteProbabilityIsTheSamplingFrequency) {
  struct Case {
    Material m;
    Vec3 wo;
    uint32_t mask;
  };
  Material mix = Glossy(0.3f, 0.0f);  // mirror
  mix.diffuse_reflectance = Rgb(0.4f, 0.2f, 0.3f);
  mix.specular_transmittance = Rgb(0.1f);  // thin
  constexpr uint32_t kSingular = kLobeGlossyReflection | kLobeSpecularReflection | kLobeSpecularTransmission;
  const std::vector<Case> cases = {
      {Dielectric(0.9f, 1.5f), FromCos(0.9f), kLobeSpecularReflection},
      {Dielectric(0.9f, 1.5f), FromCos(0.2f), kLobeSpecularReflection},
      {Dielectric(0.9f, 1.5f), FromCos(0.2f), kLobeSpecularTransmission},
      {Dielectric(0.9f, 1.5f), -FromCos(0.5f), kSingular},  // from inside
      {Dielectric(0.9f, 1.5f), -FromCos(0.1f), kSingular},  // inside, total internal reflection
      {mix, FromCos(0.6f), kSingular},
      {mix, FromCos(0.6f), kLobeDiffuseReflection},
  };
  const int n = 200'000;
  for (size_t c = 0; c < cases.size(); ++c) {
    const Bsdf bsdf(cases[c].m, kUp, kUp);
    const double p = bsdf.RouletteProbability(cases[c].wo, cases[c].mask);
    Rng rng(11, c);
    int hits = 0;
    for (int i = 0; i < n; ++i) {
      const std::optional<BsdfSample> s =
          bsdf.Sample(cases[c].wo, rng.Uniform(), rng.Uniform(), rng.Uniform(), Bsdf::Mode::kRussianRoulette);
      if (s && (s->lobe & cases[c].mask) != 0) ++hits;
    }
    const double f = double(hits) / n;
    EXPECT_NEAR(f, p, 4.0 * std::sqrt(std::max(p * (1.0 - p), 1e-6) / n) + 1e-6) << "case " << c;
  }
}

}  // namespace
}  // namespace pf
