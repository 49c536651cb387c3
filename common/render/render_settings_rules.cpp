#include "common/render/render_settings_rules.h"

#include "common/core/error.h"
#include "common/photon/photon_map_factory.h"
#include "common/render/integrator_factory.h"
#include "common/render/render_settings_table.h"
#include "common/render/setting_limits.h"

namespace pf {
namespace {

// "the photon-map integrator only (integrator = photonmap)": the integrators that read `row`.
std::string ReadersOf(const RenderSetting& row) {
  std::string titles, names;
  for (const IntegratorEntry& e : Integrators().entries()) {
    if (!e.Reads(row)) continue;
    if (!titles.empty()) {
      titles += " or ";
      names += "|";
    }
    titles += e.title;
    names += e.name;
  }
  return titles + " only (integrator = " + names + ")";
}

}  // namespace

void CheckRenderSettingRules(const JobRenderSettings& s, const SettingNamer& name) {
  if (s.integrator != IntegratorKind::kPhotonMap) return;
  if (!s.site_occlusion_test) {
    // Without precomputed sites there is nothing to switch off: refuse instead of ignoring it.
    if (s.local_pass_lookup != LocalPassLookup::kPrecomputed)
      throw InputError(name("site-occlusion-test") + ": OFF applies to the precomputed sites only; set " +
                       name("local-pass-lookup") + " = precomputed");
    if (s.local_pass_rays == 0)
      throw InputError(name("site-occlusion-test") +
                       ": OFF applies to the local pass's precomputed sites; set " + name("local-pass-rays") +
                       " > 0");
    // The camera path's test is applied to the sites' estimates too (they are the same
    // estimates, precomputed), so OFF would be silently ignored.
    if (s.occlusion_test)
      throw InputError(name("site-occlusion-test") + ": OFF contradicts " + name("occlusion-test") +
                       " = true, which tests the sites' photons too; drop one of them");
  }
  // The cache stores the local pass's gathers: without one it would be silently ignored.
  if (s.irradiance_cache_error > 0.0f && s.local_pass_rays == 0)
    throw InputError(name("irradiance-cache-error") + ": caches the local pass's gathers; set " +
                     name("local-pass-rays") + " > 0");
  if (s.adaptive_k_min > s.k)
    throw InputError(name("adaptive-k-min") + ": must be <= k (" + std::to_string(s.k) + ")");
  if (s.map_tracing == MapTracingMode::kDistributed &&
      !PhotonMapStructures().FindKind(s.structure).serializable)
    throw InputError(name("map-tracing") +
                     ": distributed tracing needs the kd-tree structure (only its maps travel)");
  // Wald 1999, §4.6: brute-force splitting emits S times the photons.
  if (s.caustic_split > 1 && s.caustic_split_method == CausticSplitMethod::kBrute &&
      s.photons * s.caustic_split > kMaxPhotonsPerMap)
    throw LimitError(name("caustic-split") +
                     ": photons × caustic_split = " + std::to_string(s.photons * s.caustic_split) +
                     " photons emitted exceeds the limit " + std::to_string(kMaxPhotonsPerMap));
  if (s.caustic_split > 1 && s.caustic_split_method == CausticSplitMethod::kMetropolis &&
      s.importance != ImportanceMode::kOff)
    throw InputError(name("caustic-split-method") +
                     ": Metropolis splitting is not combined with importance-driven maps (its mutated chains "
                     "would need their own acceptance draws); use brute or importance off");
  if (s.map_tracing == MapTracingMode::kDistributed && s.importance != ImportanceMode::kOff)
    throw InputError(name("map-tracing") +
                     ": distributed tracing does not build importance-driven maps (their importons come from "
                     "the camera); use map_tracing auto or local with importance");
}

void CheckRadiancePartsApart(const JobRenderSettings& s, const std::string& part_field) {
  if (s.integrator != IntegratorKind::kPhotonMap)
    throw InputError(part_field +
                     ": indirect needs the photonmap integrator (the path tracer has no photon-map part)");
  if (s.local_pass_rays > 0)
    throw InputError(
        part_field +
        ": indirect is not available with the local pass (local-pass-rays > 0): its parts do not "
        "add up to the whole radiance yet (docs/renderer.md)");
}

std::vector<UnusedSetting> UnusedSettings(const JobRenderSettings& s, const std::vector<std::string>& given) {
  std::vector<UnusedSetting> out;
  for (const std::string& name : given) {
    const RenderSetting* row = FindRenderSetting(name);
    if (!row) continue;
    const IntegratorEntry& integrator = Integrators().FindKind(s.integrator);
    if (!integrator.Reads(*row))
      out.push_back({name, "applies to " + ReadersOf(*row) + "; " + std::string(integrator.title) +
                               " would ignore it"});
    else if (row->applies && !row->applies(s))
      out.push_back({name, "applies only when " + std::string(row->applies_when)});
  }
  return out;
}

std::vector<std::string> NonDefaultSettings(const JobRenderSettings& s) {
  std::vector<std::string> out;
  const JobRenderSettings defaults;
  for (const RenderSetting& row : RenderSettingsTable())
    if (row.get(s) != row.get(defaults)) out.emplace_back(row.name);
  return out;
}

}  // namespace pf
