// GGX microfacet lobes in the local frame (bsdf_microfacet.h explains the model). Every
// function returns zero for a degenerate configuration instead of NaN or Inf.

#include "common/materials/bsdf_microfacet.h"

#include <algorithm>
#include <cmath>

#include "common/materials/bsdf.h"

namespace pf {

float MicrofacetAlpha(float roughness) {
  if (!(roughness > 0.0f)) return 0.0f;  // also NaN
  const float r = std::min(roughness, 1.0f);
  const float alpha = r * r;
  return alpha >= kMinMicrofacetAlpha ? alpha : 0.0f;
}

float GgxD(const Vec3& m, float alpha) {
  if (!(m.z > 0.0f)) return 0.0f;
  const float a2 = alpha * alpha;
  const float t = m.z * m.z * (a2 - 1.0f) + 1.0f;
  return a2 / (kPi * t * t);
}

float GgxLambda(const Vec3& w, float alpha) {
  const float cos2 = w.z * w.z;
  if (!(cos2 > 0.0f)) return 0.0f;
  const float tan2 = std::max(0.0f, 1.0f - cos2) / cos2;
  return 0.5f * (std::sqrt(1.0f + alpha * alpha * tan2) - 1.0f);
}

float GgxG2(const Vec3& wo, const Vec3& wi, float alpha) {
  return 1.0f / (1.0f + GgxLambda(wo, alpha) + GgxLambda(wi, alpha));
}

float GgxG1(const Vec3& w, float alpha) {
  return 1.0f / (1.0f + GgxLambda(w, alpha));
}

Vec3 SampleGgxVisibleNormal(const Vec3& wo, float alpha, float u1, float u2) {
  // Heitz 2018, listing 1: stretch wo to the hemisphere configuration, sample the projected
  // disc (warped towards the visible half), lift to the hemisphere and unstretch.
  const Vec3 vh = Normalize(Vec3(alpha * wo.x, alpha * wo.y, wo.z));
  const float len2 = vh.x * vh.x + vh.y * vh.y;
  const Vec3 t1 = len2 > 0.0f ? Vec3(-vh.y, vh.x, 0.0f) * (1.0f / std::sqrt(len2)) : Vec3(1.0f, 0.0f, 0.0f);
  const Vec3 t2 = Cross(vh, t1);
  const float r = std::sqrt(u1);
  const float phi = kTwoPi * u2;
  const float p1 = r * std::cos(phi);
  const float s = 0.5f * (1.0f + vh.z);
  const float p2 = (1.0f - s) * std::sqrt(std::max(0.0f, 1.0f - p1 * p1)) + s * r * std::sin(phi);
  const Vec3 nh = t1 * p1 + t2 * p2 + vh * std::sqrt(std::max(0.0f, 1.0f - p1 * p1 - p2 * p2));
  return Normalize(Vec3(alpha * nh.x, alpha * nh.y, std::max(1e-7f, nh.z)));
}

float GgxVisibleNormalPdf(const Vec3& wo, const Vec3& m, float alpha) {
  const float wo_m = Dot(wo, m);
  if (!(wo.z > 0.0f) || !(wo_m > 0.0f)) return 0.0f;
  return GgxG1(wo, alpha) * wo_m * GgxD(m, alpha) / wo.z;
}

Rgb SchlickFresnel(const Rgb& f0, float f90, float cos_theta) {
  const float c = 1.0f - std::clamp(cos_theta, 0.0f, 1.0f);
  const float c2 = c * c;
  const float c5 = c2 * c2 * c;
  return f0 + (Rgb(f90) - f0) * c5;
}

MicrofacetValue GgxConductor(const Vec3& wo, const Vec3& wi, float alpha, const Rgb& f0, float f90) {
  if (!(wo.z > 0.0f) || !(wi.z > 0.0f)) return {};
  const Vec3 h = wo + wi;
  const float len2 = LengthSquared(h);
  if (!(len2 > 1e-12f)) return {};
  const Vec3 m = h * (1.0f / std::sqrt(len2));
  const float wo_m = Dot(wo, m);
  if (!(wo_m > 0.0f)) return {};
  const float d = GgxD(m, alpha);
  MicrofacetValue v;
  v.f = SchlickFresnel(f0, f90, wo_m) * (d * GgxG2(wo, wi, alpha) / (4.0f * wo.z * wi.z));
  v.pdf = GgxVisibleNormalPdf(wo, m, alpha) / (4.0f * wo_m);
  if (!v.f.IsFinite() || !std::isfinite(v.pdf)) return {};
  return v;
}

RoughDielectricValue GgxDielectric(const Vec3& wo, const Vec3& wi, float alpha, float eta) {
  if (!(wo.z > 0.0f) || wi.z == 0.0f || !(eta > 0.0f)) return {};
  const bool reflection = wi.z > 0.0f;
  // The generalised half vector (Walter et al. 2007, eq. 16), on wo's side.
  const float etap = reflection ? 1.0f : eta;
  Vec3 m = wi * etap + wo;
  const float len2 = LengthSquared(m);
  if (!(len2 > 1e-12f)) return {};
  m = m * (1.0f / std::sqrt(len2));
  if (m.z < 0.0f) m = -m;
  const float wo_m = Dot(wo, m), wi_m = Dot(wi, m);
  // Back-facing microfacets (Walter et al. 2007, §5.2) contribute nothing.
  if (!(wo_m > 0.0f) || (reflection ? !(wi_m > 0.0f) : !(wi_m < 0.0f))) return {};
  RoughDielectricValue v;
  v.reflection = reflection;
  v.fresnel = FresnelDielectric(wo_m, eta);
  const float d = GgxD(m, alpha);
  const float g2 = GgxG2(wo, wi, alpha);
  const float vis = GgxVisibleNormalPdf(wo, m, alpha);
  if (reflection) {
    v.f = v.fresnel * d * g2 / (4.0f * wo.z * wi.z);
    v.pdf = vis / (4.0f * wo_m);
  } else {
    const float denom = wi_m + wo_m / eta;
    const float denom2 = denom * denom;
    if (!(denom2 > 0.0f)) return {};
    v.f = (1.0f - v.fresnel) * d * g2 * std::abs(wi_m) * wo_m / (std::abs(wi.z) * wo.z * denom2);
    v.pdf = vis * std::abs(wi_m) / denom2;
  }
  if (!std::isfinite(v.f) || !std::isfinite(v.pdf)) return {};
  return v;
}

bool RefractThrough(const Vec3& wo, const Vec3& m, float eta, Vec3* wt) {
  const float cos_i = Dot(wo, m);
  const float sin2_t = std::max(0.0f, 1.0f - cos_i * cos_i) / (eta * eta);
  if (sin2_t >= 1.0f) return false;
  const float cos_t = std::sqrt(1.0f - sin2_t);
  *wt = wo * (-1.0f / eta) + m * (cos_i / eta - cos_t);
  const float len2 = LengthSquared(*wt);
  if (!(len2 > 0.0f)) return false;
  *wt = *wt / std::sqrt(len2);
  return true;
}

}  // namespace pf
