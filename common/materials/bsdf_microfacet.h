#pragma once
// GGX / Trowbridge-Reitz microfacet lobes (Walter et al. 2007; Heitz 2014, 2018), the
// physically based reflection model of glTF 2.0 (specification, Appendix B), beside Ward's
// lobes of bsdf.h. Everything here works in the lobe's local frame: the macro normal is +z and
// wo.z > 0 (Bsdf orients the frame on wo's side, bsdf.cpp "Sidedness").
//
//  * α = r² for the glTF (perceptual) roughness r; α < kMinMicrofacetAlpha (r < 0.0316) is
//    treated as perfectly smooth: Bsdf falls back to its delta mirror / Fresnel dielectric.
//  * D: isotropic GGX, D(m) = α² / (π (cos²θm (α² − 1) + 1)²).
//  * G2: Smith *height-correlated* masking-shadowing, G2 = 1 / (1 + Λ(wo) + Λ(wi)),
//    Λ(w) = (−1 + √(1 + α² tan²θ)) / 2 (glTF Appendix B's V_GGX is G2 / (4 |cosθo| |cosθi|)).
//  * Sampling: the distribution of visible normals D_wo(m) = G1(wo) max(0, wo·m) D(m) / cosθo,
//    sampled exactly with Heitz 2018 ("Sampling the GGX Distribution of Visible Normals"); the
//    sample weight of a reflection is then F·G2/G1(wo), never above F.
//  * Conductor: f = F(wo·m) D G2 / (4 cosθo cosθi), Schlick's F = F0 + (F90 − F0)(1 − wo·m)⁵
//    (F90 = 1 for a metal, Material::microfacet_f90).
//  * Dielectric: Walter et al. 2007 reflection + refraction with the exact Fresnel term
//    (FresnelDielectric, bsdf.h). The transmission is the *adjoint* (importance / flux) BTDF,
//    without the 1/η² radiance factor, as the delta dielectric of bsdf.cpp ("No η² radiance
//    scaling"): its sample weight is (1 − F)·G2/G1, the same for camera paths and photons.
//  * Single scattering only: light that would bounce between microfacets is lost. At α = 1
//    (r = 1) a white conductor reflects 0.307 at normal incidence (0.56 at cos θo = 0.3, 0.92
//    at 0.02) of what it receives: the loss the furnace tests measure
//    (tests/common/microfacet_furnace_test.cpp, docs/results/microfacet-bsdf.md).

#include "common/core/math.h"

namespace pf {

// Below this α a microfacet lobe is a delta lobe (mirror / smooth dielectric).
inline constexpr float kMinMicrofacetAlpha = 1e-3f;

// α = r², or 0 when that is below kMinMicrofacetAlpha (or r is NaN / negative); r is clamped to 1.
float MicrofacetAlpha(float roughness);

float GgxD(const Vec3& m, float alpha);
float GgxLambda(const Vec3& w, float alpha);
// Smith height-correlated G2 and the masking G1 of one direction.
float GgxG2(const Vec3& wo, const Vec3& wi, float alpha);
float GgxG1(const Vec3& w, float alpha);
// A visible normal for wo (wo.z > 0), Heitz 2018; (u1, u2) in [0,1)².
Vec3 SampleGgxVisibleNormal(const Vec3& wo, float alpha, float u1, float u2);
// D_wo(m), the density of SampleGgxVisibleNormal over the sphere of normals.
float GgxVisibleNormalPdf(const Vec3& wo, const Vec3& m, float alpha);

// Schlick's approximation with a grazing reflectance f90 (1 for the classic form).
Rgb SchlickFresnel(const Rgb& f0, float f90, float cos_theta);

struct MicrofacetValue {
  Rgb f;             // BSDF value (no cosine)
  float pdf = 0.0f;  // solid-angle pdf of wi under VNDF sampling of this lobe (no selection)
};

// Rough conductor: f and pdf of wi (both wo.z, wi.z > 0, else zero).
MicrofacetValue GgxConductor(const Vec3& wo, const Vec3& wi, float alpha, const Rgb& f0, float f90);

// Rough dielectric. `eta` = n(other side) / n(wo's side). Values without the selection
// probability of the branch and without the transmittance tint:
//   reflection (wi.z > 0): f = F D G2 / (4 cosθo cosθi), pdf = D_wo(m) / (4 wo·m);
//   refraction (wi.z < 0): f = (1 − F) D G2 |wi·m||wo·m| / (|cosθi| cosθo (wi·m + wo·m/η)²),
//                          pdf = D_wo(m) |wi·m| / (wi·m + wo·m/η)².
// `fresnel` = F(wo·m). Zero everywhere for an impossible pair (back-facing microfacet).
struct RoughDielectricValue {
  float f = 0.0f;
  float pdf = 0.0f;
  float fresnel = 0.0f;
  bool reflection = false;
};
RoughDielectricValue GgxDielectric(const Vec3& wo, const Vec3& wi, float alpha, float eta);

// The direction refracted through microfacet m (wo·m > 0) with eta = n_t / n_i; false on total
// internal reflection.
bool RefractThrough(const Vec3& wo, const Vec3& m, float eta, Vec3* wt);

}  // namespace pf
