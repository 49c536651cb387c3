#include "common/render/render_settings_table.h"

#include <limits>
#include <stdexcept>
#include <type_traits>

#include "common/core/error.h"
#include "common/photon/importance_map.h"
#include "common/photon/photon_map_factory.h"
#include "common/render/setting_limits.h"

namespace pf {
namespace {

using S = JobRenderSettings;
using G = SettingGroup;
constexpr double kInf = std::numeric_limits<double>::infinity();

// Typed access to a member of JobRenderSettings: its value as a V (int64_t, double or bool).
template <auto M, typename V>
RenderSetting Typed(RenderSetting r, SettingType type) {
  r.type = type;
  r.get = [](const S& s) { return RenderSettingValue(V(s.*M)); };
  r.set = [](S& s, const RenderSettingValue& v) {
    s.*M = static_cast<std::remove_reference_t<decltype(s.*M)>>(std::get<V>(v));
  };
  return r;
}
template <auto M>
RenderSetting Int(RenderSetting r) {
  return Typed<M, int64_t>(std::move(r), SettingType::kInt);
}
template <auto M>
RenderSetting Real(RenderSetting r) {
  return Typed<M, double>(std::move(r), SettingType::kReal);
}
template <auto M>
RenderSetting Bool(RenderSetting r) {
  return Typed<M, bool>(std::move(r), SettingType::kBool);
}

// A choice stored as an enum: `values[i]` is the enum value of r.choices[i].
template <auto M, typename E>
RenderSetting Choice(RenderSetting r, std::vector<E> values) {
  r.type = SettingType::kChoice;
  std::vector<std::string> names;
  for (const SettingChoice& c : r.choices) names.emplace_back(c.name);
  r.get = [names, values](const S& s) {
    for (size_t i = 0; i < values.size(); ++i)
      if (values[i] == s.*M) return RenderSettingValue(names[i]);
    throw std::logic_error("settings table: a value without a choice");
  };
  r.set = [names, values](S& s, const RenderSettingValue& v) {
    for (size_t i = 0; i < names.size(); ++i)
      if (names[i] == std::get<std::string>(v)) s.*M = values[i];
  };
  return r;
}

bool DirectMayBe(const S& s, DirectLightMode m) {
  return !s.direct || *s.direct == m;
}
bool LocalPass(const S& s) {
  return s.local_pass_rays > 0;
}
bool Importance(const S& s) {
  return s.importance != ImportanceMode::kOff;
}

std::vector<RenderSetting> MakeTable() {
  std::vector<RenderSetting> t;
  // Both integrators.
  t.push_back(Choice<&S::integrator>(
      {.name = "integrator",
       .group = G::kRenderer,
       .help =
           "What estimates the radiance (pf render and pf submit choose it by default: --integrator auto, "
           "docs/renderer.md 'Choosing the integrator')",
       .choices = {{"path", "reference path tracer (NEE + MIS + Russian roulette)"},
                   {"photonmap",
                    "photon-map estimate in a distribution ray tracer (Wald 1999, 2.5) with the chapter-4 "
                    "estimators below"}}},
      std::vector{IntegratorKind::kPath, IntegratorKind::kPhotonMap}));
  t.push_back(Choice<&S::sampler>(
      {.name = "sampler",
       .group = G::kRenderer,
       .help = "The numbers behind pixel positions, lights, BSDFs, roulette, gather rays and photon paths "
               "(docs/renderer.md, 'Sampling and determinism')",
       .choices = {{"sobol", "padded Owen-scrambled Sobol points (randomised quasi-Monte Carlo)"},
                   {"independent", "independent uniform numbers, to compare"}},
       .changes_map = true},
      std::vector{SamplerKind::kSobol, SamplerKind::kIndependent}));
  // Photon maps.
  t.push_back(Int<&S::photons>({.name = "photons",
                                .group = G::kPhotonMap,
                                .help = "Photons emitted per map",
                                .min = 1,
                                .max = double(kMaxPhotonsPerMap),
                                .max_is_limit = true,
                                .changes_map = true}));
  t.push_back(Choice<&S::structure>(
      {.name = "structure",
       .group = G::kPhotonMap,
       .help = "The map's search structure",
       .choices = {{"kdtree", "left-balanced kd-tree (2.3)"},
                   {"grid", "regular grid (2.4)"},
                   {"bucket", "unbalanced kd-tree with SIMD buckets: the fastest queries", "BUCKET_KDTREE"}},
       .changes_map = true,
       .legacy_flag = "map"},
      std::vector{PhotonMapKind::kKdTree, PhotonMapKind::kGrid, PhotonMapKind::kBucketKdTree}));
  t.push_back(Choice<&S::kd_split>(
      {.name = "kd-split",
       .group = G::kPhotonMap,
       .help = "The kd-tree's split axis",
       .choices = {{"widest", "the widest extent: 2-4x faster queries in rooms (2.3, footnote 2)"},
                   {"cycle", "level % 3, the thesis's rule"}},
       .changes_map = true,
       .applies = [](const S& s) { return PhotonMapStructures().FindKind(s.structure).Reads("kd-split"); },
       .applies_when = "structure = kdtree"},
      std::vector{KdSplitRule::kWidestExtent, KdSplitRule::kLevelCycle}));
  t.push_back(Choice<&S::caustic>(
      {.name = "caustic",
       .group = G::kPhotonMap,
       .help = "A separate caustic map (L S+ D paths)",
       .choices = {{"auto", "only when the scene has specular or glossy surfaces (logged)"},
                   {"on", "always"},
                   {"off", "never"}},
       .changes_map = true,
       .legacy_flag = "caustic-map"},
      std::vector{CausticMapMode::kAuto, CausticMapMode::kOn, CausticMapMode::kOff}));
  // Radiance estimate.
  t.push_back(Int<&S::k>({.name = "k",
                          .group = G::kEstimate,
                          .help = "Nearest photons per radiance estimate",
                          .min = 1,
                          .max = double(kMaxK),
                          .max_is_limit = true,
                          .changes_map = true}));
  t.push_back(
      Real<&S::caustic_radius>({.name = "caustic-radius",
                                .group = G::kEstimate,
                                .help = "Largest caustic search radius (0 = 1% of the scene diagonal)",
                                .unit = "scene units",
                                .min = 0,
                                .max = kInf,
                                .applies = [](const S& s) { return s.caustic != CausticMapMode::kOff; },
                                .applies_when = "caustic != off"}));
  t.push_back(Real<&S::progressive_alpha>(
      {.name = "progressive-alpha",
       .group = G::kEstimate,
       .help = "Progressive plan: alpha of the radius schedule r_p^2 = r_1^2 prod_{i=1..p} (i+alpha)/(i+1) "
               "(Knaus & Zwicker 2011 suggest 2/3; 1/2 lets a disk's bias at walls' edges fall as fast as "
               "the noise: docs/results/progressive-photon-mapping.md)",
       .min = 0.01,
       .max = 0.99}));
  t.push_back(Real<&S::progressive_radius>(
      {.name = "progressive-radius",
       .group = G::kEstimate,
       .help = "Progressive plan: the first pass's search radius (0 = the disk holding about k photons "
               "of a map spread over the scene's bounding box; docs/renderer.md \"Progressive plan\")",
       .unit = "scene units",
       .min = 0,
       .max = kInf}));
  t.push_back(
      Int<&S::glossy_depth>({.name = "glossy-depth",
                             .group = G::kEstimate,
                             .help = "Glossy bounces followed before the map estimates the glossy lobe",
                             .min = 0,
                             .max = 64}));
  t.push_back(Choice<&S::direction_test>(
      {.name = "direction-test",
       .group = G::kEstimate,
       .help = "Photon direction vs surface normal test (4.1)",
       .choices = {{"in-query", "during the search: rejected photons do not count towards k"},
                   {"after", "after the search", "AFTER_QUERY"},
                   {"none", "no test"}}},
      std::vector{FeasibilityTest::kInQuery, FeasibilityTest::kAfterQuery, FeasibilityTest::kNone}));
  t.push_back(Bool<&S::occlusion_test>({.name = "occlusion-test",
                                        .group = G::kEstimate,
                                        .help = "Drop found photons whose incoming path the point cannot see "
                                                "near the photon (4.1.1): no light bleeding through "
                                                "walls, one shadow ray per photon",
                                        .changes_map = true}));
  t.push_back(Int<&S::adaptive_k_min>(
      {.name = "adaptive-k-min",
       .group = G::kEstimate,
       .help = "Shrink k down to this at borders and corners by the centre-of-gravity "
               "test (4.8; 0 = off; <= k)",
       .min = 0,
       .max = double(kMaxK)}));
  // Direct light.
  RenderSetting direct{
      .name = "direct",
      .type = SettingType::kChoice,
      .group = G::kDirectLight,
      .help = "How direct light is computed (4.2)",
      .choices = {{"auto", "photon-direct with 8 or more lights, else mc (logged)"},
                  {"photon-map", "from the map (standalone, 2.5)"},
                  {"mc", "Monte Carlo shadow rays, per light in proportion to power (4.2.1)", "MONTE_CARLO"},
                  {"photon-direct", "shadow rays split by the lights of the nearest direct photons (4.2.3)"}},
      .changes_map = true};
  direct.get = [](const S& s) {
    static const char* const kNames[] = {"photon-map", "mc", "photon-direct"};
    return RenderSettingValue(std::string(s.direct ? kNames[int(*s.direct)] : "auto"));
  };
  direct.set = [](S& s, const RenderSettingValue& v) {
    const std::string& c = std::get<std::string>(v);
    if (c == "auto")
      s.direct.reset();
    else
      s.direct = c == "photon-map" ? DirectLightMode::kNone
                 : c == "mc"       ? DirectLightMode::kMonteCarlo
                                   : DirectLightMode::kPhotonDirect;
  };
  t.push_back(std::move(direct));
  t.push_back(Int<&S::shadow_rays>(
      {.name = "shadow-rays",
       .group = G::kDirectLight,
       .help = "mc: shadow rays per shading point; photon-direct: N_total for the contributing lights",
       .min = 1,
       .max = double(kMaxShadowRays),
       .applies = [](const S& s) { return !s.direct || *s.direct != DirectLightMode::kNone; },
       .applies_when = "direct = mc, photon-direct or auto"}));
  t.push_back(Real<&S::light_uniform_fraction>(
      {.name = "light-uniform-fraction",
       .group = G::kDirectLight,
       .help = "mc: share of shadow rays drawn uniformly over the lights rather than by power (defensive "
               "sampling: bounds the weight of dim lights)",
       .min = 0,
       .max = 1,
       .applies = [](const S& s) { return DirectMayBe(s, DirectLightMode::kMonteCarlo); },
       .applies_when = "direct = mc or auto",
       .legacy_flag = "light-uniform"}));
  const auto photon_direct = [](const S& s) { return DirectMayBe(s, DirectLightMode::kPhotonDirect); };
  t.push_back(Int<&S::photon_direct_k>({.name = "photon-direct-k",
                                        .group = G::kDirectLight,
                                        .help = "photon-direct: direct photons looked up per point",
                                        .min = 1,
                                        .max = double(kMaxK),
                                        .applies = photon_direct,
                                        .applies_when = "direct = photon-direct or auto"}));
  t.push_back(Choice<&S::non_contributing>(
      {.name = "non-contributing",
       .group = G::kDirectLight,
       .help = "photon-direct: lights without photons nearby (both unbiased)",
       .choices = {{"one-random", "one sample in total, to one of them chosen by their photon count"},
                   {"each", "one sample each"}},
       .applies = photon_direct,
       .applies_when = "direct = photon-direct or auto"},
      std::vector{NonContributingMode::kOneRandom, NonContributingMode::kEachOne}));
  t.push_back(Real<&S::photon_direct_cache>(
      {.name = "photon-direct-cache",
       .group = G::kDirectLight,
       .help = "photon-direct: reuse the last neighbour set within this fraction of its radius (0 = off)",
       .min = 0,
       .max = 1,
       .applies = photon_direct,
       .applies_when = "direct = photon-direct or auto"}));
  // Local pass.
  t.push_back(Int<&S::local_pass_rays>(
      {.name = "local-pass-rays",
       .group = G::kLocalPass,
       .help = "Final gathering rays per shading point, photon map at their hits (4.3; "
               "0 = off)",
       .min = 0,
       .max = double(kMaxShadowRays),
       .changes_map = true,
       .legacy_flag = "local-pass"}));
  t.push_back(Choice<&S::local_pass_lookup>(
      {.name = "local-pass-lookup",
       .group = G::kLocalPass,
       .help = "What a gather ray reads at its hit",
       .choices = {{"full", "the photon-map estimate"},
                   {"precomputed",
                    "irradiance at every 4th photon, estimated once per map: the mean of the 4 nearest sites "
                    "visible from the hit (Christensen 1999)"}},
       .changes_map = true,
       .applies = LocalPass,
       .applies_when = "local-pass-rays > 0"},
      std::vector{LocalPassLookup::kFull, LocalPassLookup::kPrecomputed}));
  RenderSetting site = Choice<&S::site_occlusion_test>(
      {.name = "site-occlusion-test",
       .group = G::kLocalPass,
       .help = "Precomputed sites drop photons whose incoming path the site cannot see (4.1.1)",
       .choices = {{"on", "no light bleeding through walls into the sites (rooms side by side)"},
                   {"off", "faster, and no darkened corners where nothing bleeds"}},
       .changes_map = true,
       .applies =
           [](const S& s) { return LocalPass(s) && s.local_pass_lookup == LocalPassLookup::kPrecomputed; },
       .applies_when = "local-pass-rays > 0 and local-pass-lookup = precomputed"},
      std::vector{true, false});
  t.push_back(std::move(site));
  t.push_back(Real<&S::irradiance_cache_error>(
      {.name = "irradiance-cache-error",
       .group = G::kLocalPass,
       .help = "Irradiance caching (Ward 1988) of the gathers within a 16x16-pixel block: Ward's a, the "
               "largest distance/R + normal deviation a cached gather is reused at (0 = off; 0.2 is a good "
               "start)",
       .min = 0,
       .max = 1,
       .applies = LocalPass,
       .applies_when = "local-pass-rays > 0"}));
  // Importance-driven maps.
  t.push_back(Choice<&S::importance>(
      {.name = "importance",
       .group = G::kImportance,
       .help = "Importance-driven maps (4.7): importons from the camera make an importance map; a diffuse "
               "hit is stored with probability p = clamp(s * importance/mean, p_min, 1) and power phi/p. "
               "Raise photons with it",
       .choices = {{"off", "every hit is stored"},
                   {"on", "always"},
                   {"auto", "on when a short pilot would drop more than 80% of the hits (logged)"}},
       .changes_map = true},
      std::vector{ImportanceMode::kOff, ImportanceMode::kOn, ImportanceMode::kAuto}));
  t.push_back(Real<&S::importance_min_probability>(
      {.name = "importance-min-probability",
       .group = G::kImportance,
       .help = "p_min, the acceptance probability where nothing is seen (bounds those photons' power to "
               "phi/p_min)",
       .min = 0,
       .max = 1,
       .min_exclusive = true,
       .changes_map = true,
       .applies = Importance,
       .applies_when = "importance != off"}));
  t.push_back(Real<&S::importance_strength>(
      {.name = "importance-strength",
       .group = G::kImportance,
       .help = "s: every hit whose importance is at least 1/s of the mean is stored",
       .min = 0,
       .max = 1e6,
       .min_exclusive = true,
       .changes_map = true,
       .applies = Importance,
       .applies_when = "importance != off"}));
  t.push_back(Int<&S::importons>({.name = "importons",
                                  .group = G::kImportance,
                                  .help = "Importons per map (0 = one per pixel)",
                                  .min = 0,
                                  .max = double(kMaxImportons),
                                  .changes_map = true,
                                  .applies = Importance,
                                  .applies_when = "importance != off"}));
  // Caustic splitting.
  t.push_back(Int<&S::caustic_split>(
      {.name = "caustic-split",
       .group = G::kCausticSplit,
       .help = "S times the caustic photons, the global map unchanged (4.6; 1 = off; the thesis found 4-20 "
               "sufficient)",
       .min = 1,
       .max = double(kMaxCausticSplit),
       .changes_map = true}));
  t.push_back(Choice<&S::caustic_split_method>(
      {.name = "caustic-split-method",
       .group = G::kCausticSplit,
       .help = "How the caustic photons are multiplied",
       .choices = {{"brute",
                    "emit S*photons, keep non-caustic photons with 1/S at S times the power (4.6.1)"},
                   {"metropolis",
                    "S-1 jittered copies of every singular chain: fewer rays, start points can act as "
                    "secondary lights (4.6.2)"}},
       .changes_map = true,
       .applies = [](const S& s) { return s.caustic_split > 1; },
       .applies_when = "caustic-split > 1"},
      std::vector{CausticSplitMethod::kBrute, CausticSplitMethod::kMetropolis}));
  // Farm.
  t.push_back(Choice<&S::map_tracing>(
      {.name = "map-tracing",
       .group = G::kFarm,
       .help = "Who traces a farm job's photon maps (pf render --workers N, pf submit); the image is the "
               "same",
       .choices = {{"auto", "traced once in pieces and built once when several tasks use a kd-tree map"},
                   {"local", "each worker traces the maps of its tasks"},
                   {"distributed", "always traced once (kdtree only)"}}},
      std::vector{MapTracingMode::kAuto, MapTracingMode::kLocal, MapTracingMode::kDistributed}));
  return t;
}

}  // namespace

const std::vector<RenderSetting>& RenderSettingsTable() {
  static const std::vector<RenderSetting> table = MakeTable();
  return table;
}

const RenderSetting* FindRenderSetting(std::string_view name) {
  for (const RenderSetting& row : RenderSettingsTable())
    if (row.name == name) return &row;
  return nullptr;
}

std::vector<std::string> RenderSettingNames() {
  std::vector<std::string> names;
  for (const RenderSetting& row : RenderSettingsTable()) names.emplace_back(row.name);
  return names;
}

RenderSettingValue DefaultRenderSettingValue(const RenderSetting& row) {
  return row.get(JobRenderSettings{});
}

void SetRenderSetting(JobRenderSettings& s, std::string_view name, std::string_view text,
                      const std::string& label) {
  const RenderSetting* row = FindRenderSetting(name);
  if (!row)
    throw InputError(label + ": no setting is called '" + std::string(name) + "' (pf settings lists them)");
  row->set(s, ParseRenderSettingValue(*row, text, label));
}

}  // namespace pf
