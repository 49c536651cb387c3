// common/render/integrator_factory.h: every registered integrator builds; an unknown name lists
// the known ones; each builder refuses a setting it reads that is out of range, naming it; the
// registry's names are the `integrator` setting's choices; which settings an integrator reads
// agrees with the wire's layout and with UnusedSettings.

#include "common/render/integrator_factory.h"

#include <gmock/gmock.h>
#include <gtest/gtest.h>

#include <functional>
#include <set>
#include <string>
#include <vector>

#include "common/core/error.h"
#include "common/render/render_settings_rules.h"
#include "common/render/render_settings_table.h"
#include "common/render/scene_runtime.h"
#include "tests/common/test_scenes.h"
#include "tests/util/input_error.h"

namespace pf {
namespace {

using pf::testing::FloorUnderSquareLight;
using pf::testing::InputErrorOf;
using ::testing::HasSubstr;

std::vector<std::string> ChoiceNames(const char* setting) {
  std::vector<std::string> names;
  for (const SettingChoice& c : FindRenderSetting(setting)->choices) names.emplace_back(c.name);
  return names;
}

// Resolved photon-map settings and maps built from them for `scene`.
struct Built {
  explicit Built(const SceneRuntime& scene) {
    settings.photons = 1000;
    settings = settings.Resolved(scene.description);
    PhotonMapsOptions mo = settings.MapsOptions();
    maps = PhotonMaps::Build(scene.accel, scene.lights, mo);
  }
  IntegratorInputs Inputs(const SceneRuntime& scene) const {
    return {.scene = &scene.accel, .lights = &scene.lights, .maps = &maps};
  }
  JobRenderSettings settings;
  PhotonMaps maps;
};

TEST(IntegratorFactory, NamesAreTheIntegratorSettingsChoices) {
  EXPECT_EQ(Integrators().Names(), ChoiceNames("integrator"));
  // Every choice's enum value has its entry, and the entry its name.
  for (const IntegratorEntry& e : Integrators().entries()) {
    JobRenderSettings s;
    SetRenderSetting(s, "integrator", e.name, "integrator");
    EXPECT_EQ(s.integrator, e.kind) << e.name;
    EXPECT_EQ(&Integrators().FindKind(e.kind), &e);
  }
}

TEST(IntegratorFactory, EveryRegisteredNameBuilds) {
  const SceneRuntime scene(FloorUnderSquareLight(1.0f));
  const Built built(scene);
  for (const std::string& name : Integrators().Names()) {
    const std::unique_ptr<Integrator> integrator = MakeIntegrator(name, built.settings, built.Inputs(scene));
    ASSERT_NE(integrator, nullptr) << name;
    EXPECT_EQ(integrator->name(), name);
  }
}

TEST(IntegratorFactory, UnknownNameListsTheKnownOnes) {
  const std::string error = InputErrorOf([] { Integrators().Find("photonmapper", "integrator"); });
  EXPECT_THAT(error,
              HasSubstr("integrator: no integrator is called 'photonmapper' (known: path or photonmap)"));
  EXPECT_THAT(InputErrorOf([] { MakeIntegrator("bdpt", JobRenderSettings{}, {}); }),
              HasSubstr("no integrator is called 'bdpt'"));
}

TEST(IntegratorFactory, EachBuilderRefusesASettingItReadsNamingIt) {
  const SceneRuntime scene(FloorUnderSquareLight(1.0f));
  const Built built(scene);
  // sampler: read by both integrators; k: by the photon-map integrator only.
  for (const std::string& name : Integrators().Names()) {
    JobRenderSettings s = built.settings;
    s.sampler = static_cast<SamplerKind>(99);
    EXPECT_THROW(MakeIntegrator(name, s, built.Inputs(scene)), std::logic_error) << name;
  }
  // The photon-map integrator's own settings, alone and against each other.
  const auto photon_map_error = [&](const std::function<void(JobRenderSettings&)>& change) {
    JobRenderSettings s = built.settings;
    change(s);
    EXPECT_NE(MakeIntegrator("path", s, built.Inputs(scene)), nullptr);  // it reads none of them
    return InputErrorOf([&] { MakeIntegrator("photonmap", s, built.Inputs(scene)); });
  };
  EXPECT_THAT(photon_map_error([](JobRenderSettings& s) { s.k = 0; }), HasSubstr("k: must be"));
  EXPECT_THAT(photon_map_error([](JobRenderSettings& s) { s.shadow_rays = 0; }),
              HasSubstr("shadow-rays: must be"));
  // A resource limit is the job's (checked where it enters), not the integrator's: it renders beyond.
  EXPECT_EQ(photon_map_error([](JobRenderSettings& s) { s.k = 100000; }), "(no error)");
  EXPECT_THAT(photon_map_error([](JobRenderSettings& s) { s.adaptive_k_min = s.k + 1; }),
              HasSubstr("adaptive-k-min: must be <= k"));
}

TEST(IntegratorFactory, ThePhotonMapIntegratorNeedsItsMaps) {
  const SceneRuntime scene(FloorUnderSquareLight(1.0f));
  const Built built(scene);
  IntegratorInputs inputs = built.Inputs(scene);
  inputs.maps = nullptr;
  EXPECT_THROW(MakeIntegrator("photonmap", built.settings, inputs), std::logic_error);
  EXPECT_TRUE(Integrators().FindKind(IntegratorKind::kPhotonMap).UsesPhotonMaps());
  EXPECT_FALSE(Integrators().FindKind(IntegratorKind::kPath).UsesPhotonMaps());
}

// Which integrator reads a setting has one source, the entries' groups: the wire's layout
// (PhotonMapOnly: a field of PhotonMapSettings) is the rows the path tracer does not read, and
// UnusedSettings reports exactly the rows the chosen integrator does not read.
TEST(IntegratorFactory, SettingsReadAgreeWithTheWireAndUnusedSettings) {
  const std::vector<std::string> all = RenderSettingNames();
  for (const IntegratorEntry& e : Integrators().entries()) {
    JobRenderSettings s;
    s.integrator = e.kind;
    std::set<std::string> unused;
    for (const UnusedSetting& u : UnusedSettings(s, all))
      if (u.reason.find("ignore") != std::string::npos) unused.insert(u.name);
    for (const RenderSetting& row : RenderSettingsTable()) {
      EXPECT_EQ(e.Reads(row), !unused.count(std::string(row.name))) << e.name << " " << row.name;
      if (e.kind == IntegratorKind::kPath) {
        EXPECT_EQ(e.Reads(row), !row.PhotonMapOnly()) << row.name;
      }
    }
  }
  JobRenderSettings path;
  path.integrator = IntegratorKind::kPath;
  const std::vector<UnusedSetting> unused = UnusedSettings(path, {"photons"});
  ASSERT_EQ(unused.size(), 1u);
  EXPECT_EQ(
      unused[0].reason,
      "applies to the photon-map integrator only (integrator = photonmap); the path tracer would ignore "
      "it");
}

}  // namespace
}  // namespace pf
