// The rough (GGX) dielectric of Bsdf: Walter et al. 2007's reflection and refraction through
// microfacets, sampled with visible normals (Heitz 2018); the microfacet functions are in
// bsdf_microfacet.cpp. Like the smooth dielectric (bsdf.cpp, SampleDielectric), the front face
// is outside (index 1) and the inside has index `ior`; reflection is chosen with probability
// F(wo·m) of the sampled microfacet m and refraction with 1 − F (times min(1, mean τs) in the
// photon walk's roulette, the rest absorbed); reflection is untinted, refraction tinted by τs.
// Sidedness is judged against the geometric normal as for every lobe (bsdf.cpp, "Sidedness"),
// and the shading frame must agree with it.

#include <cmath>

#include "common/materials/bsdf.h"
#include "common/materials/bsdf_microfacet.h"

namespace pf {

void Bsdf::RoughBranches(float fresnel, Mode mode, uint32_t lobes, float* p_reflect, float* p_refract) const {
  const bool reflect_allowed = (lobes & kLobeGlossyReflection) != 0;
  const bool refract_allowed = (lobes & kLobeGlossyTransmission) != 0;
  *p_reflect = reflect_allowed ? fresnel : 0.0f;
  *p_refract = refract_allowed ? 1.0f - fresnel : 0.0f;
  if (mode == Mode::kRussianRoulette) {
    *p_refract *= lobes_.p_roulette[kSlotSpecularT];
  } else if (!(reflect_allowed && refract_allowed)) {
    const float sum = *p_reflect + *p_refract;  // renormalise over the allowed branch
    *p_reflect = sum > 0.0f ? *p_reflect / sum : 0.0f;
    *p_refract = sum > 0.0f ? *p_refract / sum : 0.0f;
  }
}

std::optional<BsdfSample> Bsdf::SampleRoughDielectric(const Vec3& wo, const Vec3& n, float side, float u_lobe,
                                                      float u1, float u2, Mode mode, uint32_t lobes) const {
  const Frame frame(n);
  const Vec3 local_o = frame.ToLocal(wo);
  if (!(local_o.z > 0.0f)) return std::nullopt;
  const Vec3 m = SampleGgxVisibleNormal(local_o, lobes_.alpha, u1, u2);
  const float wo_m = Dot(local_o, m);
  if (!(wo_m > 0.0f)) return std::nullopt;
  const float eta = EtaFor(side);
  float p_reflect, p_refract;
  RoughBranches(FresnelDielectric(wo_m, eta), mode, lobes, &p_reflect, &p_refract);
  BsdfSample s;
  Vec3 local_i;
  if (u_lobe < p_reflect) {
    local_i = m * (2.0f * wo_m) - local_o;
    s.lobe = kLobeGlossyReflection;
  } else {
    // In kNormalized the two branches sum to 1 (a u_lobe rounded past it refracts); in the
    // roulette the rest is absorption.
    const bool absorbed = mode == Mode::kRussianRoulette && !(u_lobe < p_reflect + p_refract);
    if (absorbed || !(p_refract > 0.0f) || !RefractThrough(local_o, m, eta, &local_i)) return std::nullopt;
    s.lobe = kLobeGlossyTransmission;
  }
  s.wi = Normalize(frame.ToWorld(local_i));
  const float cos_g = Dot(s.wi, ng_) * side;
  if (s.lobe == kLobeGlossyReflection ? !(cos_g > 0.0f) : !(cos_g < 0.0f)) return std::nullopt;
  // The weight from Eval and Pdf (= τs^[refraction]·G2/G1 over the branch probability's share),
  // so that Sample, Eval and Pdf agree to rounding.
  Rgb f;
  float pdf;
  EvalPdfRoughDielectric(wo, s.wi, lobes, mode, &f, &pdf);
  s.pdf = pdf;
  s.weight = f * (AbsCosTheta(s.wi) / pdf);
  const bool usable = pdf > 0.0f && s.weight.IsFinite() && IsFinite(s.wi);
  return usable ? std::optional<BsdfSample>(s) : std::nullopt;
}

void Bsdf::EvalPdfRoughDielectric(const Vec3& wo, const Vec3& wi, uint32_t lobes, Mode mode, Rgb* f,
                                  float* pdf) const {
  *f = Rgb(0.0f);
  *pdf = 0.0f;
  Vec3 n;
  float side;
  if (!LobeNormal(wo, &n, &side)) return;
  const float cos_g = Dot(wi, ng_) * side;
  if (cos_g == 0.0f || !std::isfinite(cos_g)) return;
  const bool reflection = cos_g > 0.0f;
  if ((lobes & (reflection ? kLobeGlossyReflection : kLobeGlossyTransmission)) == 0) return;
  const Frame frame(n);
  const Vec3 local_o = frame.ToLocal(wo), local_i = frame.ToLocal(wi);
  if (reflection != (local_i.z > 0.0f)) return;  // the shading frame disagrees with ng
  const RoughDielectricValue v = GgxDielectric(local_o, local_i, lobes_.alpha, EtaFor(side));
  if (!(v.pdf > 0.0f)) return;
  float p_reflect, p_refract;
  RoughBranches(v.fresnel, mode, lobes, &p_reflect, &p_refract);
  *f = reflection ? Rgb(v.f) : material_->specular_transmittance * v.f;
  *pdf = (reflection ? p_reflect : p_refract) * v.pdf;
  if (!f->IsFinite() || !std::isfinite(*pdf)) {
    *f = Rgb(0.0f);
    *pdf = 0.0f;
  }
}

}  // namespace pf
