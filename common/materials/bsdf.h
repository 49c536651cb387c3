#pragma once
// The BSDF of one shading point: Ward's model (Wald 1999, §2.1) — Lambertian diffuse,
// perfect specular mirror, isotropic glossy Ward lobe, diffuse and specular transmission, and
// Fresnel dielectrics — built from a `Material` and the local frame.
//
// Conventions (pbrt-like):
//  * Directions are unit vectors in world space pointing AWAY from the surface: `wo` towards
//    the viewer (for photons: towards where the photon came from), `wi` the other direction.
//  * Eval/Pdf cover only the non-delta lobes; delta lobes (mirror, refraction, thin straight
//    transmission) are reached only through Sample and report is_delta = true.
//  * Sample's `weight` = f·|cos θi| / pdf, including the lobe-selection probability, so a path
//    throughput is simply multiplied by it.
//  * Lobe selection: by the lobes' albedos (channel means). Mode::kRussianRoulette selects with
//    the *unnormalised* means and returns nullopt (absorption) otherwise: the photon random
//    walk of §2.2 (per-channel power correction ρ/P is then in `weight`).

#include <cstdint>
#include <optional>

#include "common/core/math.h"
#include "common/scene/scene.h"

namespace pf {

enum LobeFlags : uint32_t {
  kLobeNone = 0,
  kLobeDiffuseReflection = 1u << 0,
  kLobeGlossyReflection = 1u << 1,
  kLobeSpecularReflection = 1u << 2,  // perfect mirror or Fresnel reflection (delta)
  kLobeDiffuseTransmission = 1u << 3,
  kLobeSpecularTransmission = 1u << 4,  // refraction or thin straight-through (delta)
  kLobeGlossyTransmission = 1u << 5,    // rough (GGX) refraction (bsdf_microfacet.h)
  kLobeAll = (1u << 6) - 1,
};

// Wald's classification (§2.1): diffuse interactions are regular (D), specular and glossy ones
// singular (S). Used for caustic-vs-diffuse photon storage. Every microfacet (GGX) lobe is
// glossy, hence singular, at every roughness from the delta threshold (α = r² >= 1e-3,
// bsdf_microfacet.h) up to r = 1: photons are stored only on Lambertian lobes, because the
// photon map shader's estimates (precomputed irradiance, irradiance cache, gathering) are
// ρd/π·E and would be wrong for a GGX lobe however rough.
constexpr bool IsSingular(uint32_t lobe) {
  return (lobe & (kLobeGlossyReflection | kLobeSpecularReflection | kLobeSpecularTransmission |
                  kLobeGlossyTransmission)) != 0;
}
// A non-delta singular lobe (Ward or GGX reflection, GGX refraction).
constexpr bool IsGlossy(uint32_t lobe) {
  return (lobe & (kLobeGlossyReflection | kLobeGlossyTransmission)) != 0;
}

struct BsdfSample {
  Vec3 wi;
  Rgb weight;        // f·|cos θi| / pdf (delta lobes: reflectance·Fresnel / selection prob)
  float pdf = 0.0f;  // solid-angle pdf incl. lobe selection; for delta lobes the selection prob
  uint32_t lobe = kLobeNone;
  bool is_delta = false;
};

// What a Bsdf takes from its Material alone: the lobe kinds and the selection probabilities
// (channel means of ρd, ρs, τd, τs, §2.2). The same for every hit on the material, so a loop
// that builds a Bsdf at every hit (the photon walk of §2.2: 8 % of its time went to these means)
// computes them once per material with Of() and hands them to the constructor below; the values
// are those the plain constructor computes, so either way gives the same Bsdf bit for bit.
struct BsdfLobes {
  enum Slot { kSlotDiffuseR = 0, kSlotSpecularR, kSlotDiffuseT, kSlotSpecularT, kNumSlots };

  static BsdfLobes Of(const Material& material);

  float alpha = 0.0f;       // Ward (or GGX) α of the reflection lobe; 0 = mirror
  bool glossy = false;      // ρs is a Ward lobe (α >= 1e-4) or a GGX one, else a mirror
  bool dielectric = false;  // τs with ior != 1: Fresnel dielectric only
  // Material::Microfacet::kConductor: ρs is GGX (glossy) or a mirror with Schlick's Fresnel.
  bool conductor = false;
  // Material::Microfacet::kDielectric with α >= 1e-3 (else `dielectric`): GGX reflection and
  // refraction (Walter et al. 2007) only; alpha is its GGX α.
  bool rough_dielectric = false;
  float mean[kNumSlots] = {};          // channel means of ρd, ρs, τd, τs (>= 0)
  float p_normalized[kNumSlots] = {};  // Mode::kNormalized selection probabilities
  float p_roulette[kNumSlots] = {};    // Mode::kRussianRoulette selection probabilities
};

class Bsdf {
 public:
  enum class Mode { kNormalized, kRussianRoulette };

  // `ng`: geometric normal of the triangle's front face (unit). `ns`: shading normal (unit;
  // flipped by the constructor into ng's hemisphere if needed). The material outlives the Bsdf.
  Bsdf(const Material& material, const Vec3& ns, const Vec3& ng);
  // The same Bsdf from the material's precomputed lobes (`lobes` must be BsdfLobes::Of(material)).
  Bsdf(const Material& material, const BsdfLobes& lobes, const Vec3& ns, const Vec3& ng);

  // f(wo, wi) of the non-delta lobes, without cosine. Zero if wi and wo are on the wrong sides
  // for every lobe (judged against the geometric normal).
  Rgb Eval(const Vec3& wo, const Vec3& wi) const;
  // Solid-angle pdf with which Sample(kNormalized) produces wi through a non-delta lobe.
  float Pdf(const Vec3& wo, const Vec3& wi) const;
  // Samples an outgoing direction. u_lobe in [0,1) picks the lobe, (u1, u2) the direction.
  std::optional<BsdfSample> Sample(const Vec3& wo, float u_lobe, float u1, float u2,
                                   Mode mode = Mode::kNormalized) const;
  // Sample restricted to the lobes in `lobes` (a LobeFlags mask), as if the others were absent:
  // kNormalized renormalises the selection over the allowed lobes (weight = EvalLobes·|cos|/pdf
  // of the allowed non-delta lobes), kRussianRoulette turns the others' probability into
  // absorption. A dielectric's Fresnel reflection and refraction count as separate lobes
  // (kLobeSpecularReflection / kLobeSpecularTransmission). E[weight] = albedo of the allowed
  // lobes. Used by the photon map shader (§2.5): diffuse from photons, singular lobes traced.
  std::optional<BsdfSample> Sample(const Vec3& wo, float u_lobe, float u1, float u2, Mode mode,
                                   uint32_t lobes) const;

  // Probability that Sample(wo, u, ·, ·, kRussianRoulette) picks a lobe of `lobes` (a LobeFlags
  // mask) for a uniform u: the photon walk's lobe-choice probability (§2.2). Metropolis caustic
  // splitting (Wald 1999, §4.6.2) needs it as a function of wo for its acceptance ratio.
  float RouletteProbability(const Vec3& wo, uint32_t lobes) const;
  // The axis of the cosine lobes for this wo (the shading normal on wo's side, or the geometric
  // one when wo is below the shading hemisphere); nullopt for wo in the surface plane.
  std::optional<Vec3> LobeAxis(const Vec3& wo) const;

  bool HasNonDelta() const;             // has any lobe that Eval can see (next-event estimation useful)
  bool HasDiffuse() const;              // diffuse reflection or transmission (photon storage, §2.2)
  bool HasLobes(uint32_t lobes) const;  // has any lobe of the LobeFlags mask (delta ones too)
  const Material& material() const { return *material_; }
  const Vec3& shading_normal() const { return ns_; }
  const Vec3& geometric_normal() const { return ng_; }

  // Eval restricted to the non-delta lobes in `lobes` (a LobeFlags mask); Eval(wo, wi) ==
  // EvalLobes(wo, wi, all). The photon map shader (§2.5) estimates only the diffuse lobes
  // from photons and traces the glossy one.
  Rgb EvalLobes(const Vec3& wo, const Vec3& wi, uint32_t lobes) const;
  // |cos θ| of w against the shading normal: the cosine included in Sample's weight, and the
  // one to multiply Eval by (e.g. for next-event estimation).
  float AbsCosTheta(const Vec3& w) const { return std::abs(Dot(w, ns_)); }

 private:
  // Lobe slots (bsdf.cpp explains the selection rules).
  static constexpr int kSlotDiffuseR = BsdfLobes::kSlotDiffuseR, kSlotSpecularR = BsdfLobes::kSlotSpecularR,
                       kSlotDiffuseT = BsdfLobes::kSlotDiffuseT, kSlotSpecularT = BsdfLobes::kSlotSpecularT,
                       kNumSlots = BsdfLobes::kNumSlots;

  // The normal that orients the lobes for this wo: the shading normal on wo's side of ng (ng
  // itself if wo is below that shading hemisphere). `side` = sign(wo·ng). False if wo lies in
  // the surface plane or the Bsdf is degenerate.
  // `shading` (optional): whether *n is the shading normal (not ng).
  bool LobeNormal(const Vec3& wo, Vec3* n, float* side, bool* shading = nullptr) const;
  // The LobeFlags bit of a (non-dielectric) slot.
  uint32_t SlotLobe(int slot) const;
  // Selection probabilities of `mode` restricted to `lobes` (see the restricted Sample).
  void SelectionProbabilities(Mode mode, uint32_t lobes, float probs[kNumSlots]) const;
  // f and Σ probs[slot]·pdf_slot over the non-delta lobes in `lobes`.
  void EvalPdf(const Vec3& wo, const Vec3& wi, uint32_t lobes, const float* probs, Rgb* f, float* pdf) const;
  std::optional<BsdfSample> SampleDielectric(const Vec3& wo, const Vec3& n, float side, float u_lobe,
                                             Mode mode, uint32_t lobes) const;
  // The rough dielectric (bsdf_rough_dielectric.cpp): its two branch probabilities for the
  // Fresnel term F, the EvalPdf of its lobes, and Sample.
  void RoughBranches(float fresnel, Mode mode, uint32_t lobes, float* p_reflect, float* p_refract) const;
  void EvalPdfRoughDielectric(const Vec3& wo, const Vec3& wi, uint32_t lobes, Mode mode, Rgb* f,
                              float* pdf) const;
  std::optional<BsdfSample> SampleRoughDielectric(const Vec3& wo, const Vec3& n, float side, float u_lobe,
                                                  float u1, float u2, Mode mode, uint32_t lobes) const;
  // The index ratio n(other side) / n(wo's side) of the dielectric for wo on `side`.
  float EtaFor(float side) const { return side > 0.0f ? material_->ior : 1.0f / material_->ior; }

  const Material* material_;
  Vec3 ns_, ng_;
  bool valid_ = false;  // ng usable
  BsdfLobes lobes_;
};

// Bsdf::Sample in Mode::kRussianRoulette at a hit on a flat triangle, without building a Bsdf:
// the photon walk's per-hit roulette (Wald 1999, §2.2) for its two commonest outcomes. Made once
// per material (Of); At() gives, for a hit whose shading normal is its geometric normal bit for
// bit:
//   kAbsorbed — Sample would return nullopt (u_lobe past the roulette's lobes, or wo or the
//               sampled wi on the wrong side);
//   kDiffuse  — Sample would choose the diffuse reflection lobe, the first of its cdf walk, and
//               return exactly *wi and `diffuse_weight` (ρd/P: with ns = ng the lobe normal is
//               the shading normal on wo's side, bsdf.cpp);
//   kBsdf     — any other case (another lobe — GGX ones included —, a smooth hit, a dielectric
//               smooth or rough, an unusable ng): call Bsdf::Sample.
// The same floating-point operations as Sample, in the same order (and no FMA contraction,
// CMakeLists.txt), so the photons are the same bit for bit (BsdfWalkRoulette tests); a photon
// bounce built a Bsdf and walked Sample's general path, a third of a Cornell photon ray's
// instructions outside Embree (docs/results/kernel.md §4, Run 3).
struct WalkRoulette {
  enum class Outcome { kAbsorbed, kDiffuse, kBsdf };

  static WalkRoulette Of(const Material& material, const BsdfLobes& lobes) {
    WalkRoulette w;
    w.textured = IsTextured(material);
    w.dielectric = lobes.dielectric || lobes.rough_dielectric;
    w.has_diffuse = !w.dielectric && (lobes.mean[BsdfLobes::kSlotDiffuseR] > 0.0f ||
                                      lobes.mean[BsdfLobes::kSlotDiffuseT] > 0.0f);
    // A metallic-roughness texture can lower metallic below 1 and a transmission texture can
    // lower transmission to 0 at some texels, giving the surface a diffuse lobe there: storing is
    // the material's (photon_tracer.cpp), so it stores wherever that can happen (an opaque,
    // not wholly metallic texel of a base colour that is not black).
    if (const std::optional<MetallicRoughness>& p = material.metallic_roughness;
        p && (material.metallic_roughness_texture >= 0 || material.transmission_texture >= 0) &&
        (p->transmission == 0.0f || material.transmission_texture >= 0) &&
        (p->metallic < 1.0f || material.metallic_roughness_texture >= 0) && !p->base_color.IsBlack())
      w.has_diffuse = true;
    w.p_diffuse = lobes.p_roulette[BsdfLobes::kSlotDiffuseR];
    w.diffuse_weight = material.diffuse_reflectance / w.p_diffuse;
    // Sample's cdf walk: the positive probabilities summed in slot order; u_lobe below the
    // running sum picks that slot, past the last sum it is absorption.
    for (float p : lobes.p_roulette)
      if (p > 0.0f) w.absorb_from += p;
    return w;
  }

  // Whether Bsdf(material, ·, ng).HasDiffuse() holds: the hit stores a photon (§2.2).
  static bool UsableNormal(const Vec3& ng) { return IsFinite(ng) && LengthSquared(ng) > 1e-20f; }
  bool Stores(const Vec3& ng) const { return has_diffuse && UsableNormal(ng); }

  // `ng`: the hit's geometric normal as the Bsdf constructor gets it; `flat`: its shading normal
  // is ng bit for bit.
  Outcome At(const Vec3& ng, bool flat, const Vec3& wo, float u_lobe, float u1, float u2, Vec3* wi) const {
    if (dielectric) return Outcome::kBsdf;
    if (!UsableNormal(ng)) return Outcome::kBsdf;
    if (!(u_lobe < absorb_from)) return Outcome::kAbsorbed;  // whatever the normals
    if (!flat || !(u_lobe < p_diffuse)) return Outcome::kBsdf;
    const Vec3 n_g = LengthSquared(ng) == 1.0f ? ng : Normalize(ng);  // the constructor's ng_
    const float cos_g = Dot(wo, n_g);
    if (!(std::abs(cos_g) > 0.0f)) return Outcome::kAbsorbed;  // wo in the surface plane
    const float side = cos_g > 0.0f ? 1.0f : -1.0f;
    const Vec3 n = n_g * side;  // ns_ * side: the shading normal on wo's side
    *wi = Frame(n).ToWorld(CosineHemisphereFast(u1, u2));
    if (!(Dot(*wi, n_g) * side > 0.0f) || !(Dot(*wi, n) > 0.0f)) return Outcome::kAbsorbed;
    if (!diffuse_weight.IsFinite() || !IsFinite(*wi)) return Outcome::kAbsorbed;
    return Outcome::kDiffuse;
  }

  // The material has a texture (scene/surface_material.h): this roulette is the untextured
  // material's, and the walk makes one per hit instead. Kept here so that the walk's per-hit test
  // reads the table it reads anyway, not the material.
  bool textured = false;
  bool dielectric = false;  // smooth or rough: always the general path
  bool has_diffuse = false;
  float p_diffuse = 0.0f;    // the roulette's probability of the diffuse reflection lobe
  float absorb_from = 0.0f;  // u_lobe >= this: absorbed
  Rgb diffuse_weight;        // ρd / p_diffuse: Sample's weight for that lobe, the same division
};

// Fresnel reflectance of a dielectric interface for unpolarised light. cos_i >= 0 is the cosine
// on the incident side, eta = n_transmitted / n_incident. Returns 1 on total internal reflection.
float FresnelDielectric(float cos_i, float eta);

}  // namespace pf
