// The settings table (common/render/render_settings_table.h) and what is made from it: the map
// key and the EXR header cover exactly its rows; its rules and "does not apply" checks.

#include <gmock/gmock.h>
#include <gtest/gtest.h>

#include <set>
#include <string>

#include "common/core/error.h"
#include "common/render/render_settings_rules.h"
#include "common/render/render_settings_table.h"
#include "common/render/render_settings_text.h"

namespace pf {
namespace {

using ::testing::HasSubstr;

// A value of `row` other than its value in `s`, within its range.
RenderSettingValue OtherValue(const RenderSetting& row, const JobRenderSettings& s) {
  const RenderSettingValue v = row.get(s);
  switch (row.type) {
    case SettingType::kBool:
      return !std::get<bool>(v);
    case SettingType::kInt: {
      const int64_t i = std::get<int64_t>(v);
      return i < int64_t(row.max) ? i + 1 : i - 1;
    }
    case SettingType::kReal: {
      const double d = std::get<double>(v);
      return d == 0.5 ? 0.25 : 0.5;
    }
    case SettingType::kChoice:  // not auto: the map key needs resolved settings
      for (const SettingChoice& c : row.choices)
        if (c.name != std::get<std::string>(v) && c.name != "auto") return std::string(c.name);
  }
  return v;
}

// Every input of the photon maps' options, as text: what a map is built from.
std::string MapsOptionsText(const JobRenderSettings& s) {
  const PhotonMapsOptions o = s.MapsOptions();
  return std::to_string(o.tracing.photons) + "," + std::to_string(int(o.tracing.sampler)) + "," +
         std::to_string(o.tracing.caustic_split) + "," + std::to_string(int(o.tracing.caustic_split_method)) +
         "," + std::to_string(int(o.kind)) + "," + std::to_string(int(o.structure.kd_split_rule)) + "," +
         std::to_string(o.structure.grid.expected_k) + "," + std::to_string(int(o.caustic)) + "," +
         std::to_string(o.separate_direct) + std::to_string(o.direct_map) + std::to_string(o.keep_light_ids) +
         std::to_string(o.keep_origins) + "," + std::to_string(int(o.importance.mode)) + "," +
         std::to_string(o.importance.min_probability) + "," + std::to_string(o.importance.strength) + "," +
         std::to_string(o.importance.importons) + "," + std::to_string(o.importance.diffuse_bounces);
}

// Resolved settings under which (almost) every setting has an effect.
std::vector<JobRenderSettings> Bases() {
  JobRenderSettings mc;
  mc.direct = DirectLightMode::kMonteCarlo;
  mc.caustic = CausticMapMode::kOn;
  mc.local_pass_rays = 8;
  mc.local_pass_lookup = LocalPassLookup::kPrecomputed;
  mc.importance = ImportanceMode::kOn;
  mc.caustic_split = 4;
  JobRenderSettings photon_direct = mc;
  photon_direct.direct = DirectLightMode::kPhotonDirect;
  return {mc, photon_direct};
}

TEST(RenderSettingsTable, RowsAreWellFormed) {
  std::set<std::string> names;
  for (const RenderSetting& row : RenderSettingsTable()) {
    const std::string name(row.name);
    SCOPED_TRACE(name);
    EXPECT_TRUE(names.insert(name).second) << "twice";
    EXPECT_EQ(name.find_first_not_of("abcdefghijklmnopqrstuvwxyz-"), std::string::npos) << "not kebab-case";
    EXPECT_FALSE(row.help.empty());
    EXPECT_EQ(row.applies == nullptr, row.applies_when.empty());
    EXPECT_EQ(row.type == SettingType::kChoice, !row.choices.empty());
    EXPECT_EQ(FindRenderSetting(name), &row);
    // The default is valid, and a setting's text reads back as the same setting.
    const RenderSettingValue d = DefaultRenderSettingValue(row);
    EXPECT_NO_THROW(CheckRenderSettingValue(row, d, name));
    for (const RenderSettingValue& v : {d, OtherValue(row, JobRenderSettings{})}) {
      JobRenderSettings s, again;
      row.set(s, v);
      row.set(again, ParseRenderSettingValue(row, FormatRenderSettingValue(row.get(s)), name));
      EXPECT_EQ(row.get(again), row.get(s));
    }
  }
  EXPECT_EQ(RenderSettingsTable().front().name, "integrator");  // read first from the wire
  EXPECT_EQ(FindRenderSetting("no-such-setting"), nullptr);
}

TEST(RenderSettingsTable, ValuesAreCheckedAndErrorsNameTheSetting) {
  const RenderSetting& k = *FindRenderSetting("k");
  EXPECT_THROW(ParseRenderSettingValue(k, "12x", "--set k"), InputError);
  try {
    ParseRenderSettingValue(k, "0", "--set k");
    ADD_FAILURE();
  } catch (const InputError& e) {
    EXPECT_THAT(e.what(), HasSubstr("--set k: must be >= 1"));
  }
  EXPECT_THROW(ParseRenderSettingValue(k, "10001", "k"), LimitError);
  EXPECT_THROW(ParseRenderSettingValue(*FindRenderSetting("light-uniform-fraction"), "nan", "x"), InputError);
  EXPECT_THROW(ParseRenderSettingValue(*FindRenderSetting("importance-min-probability"), "0", "x"),
               InputError);
  EXPECT_THROW(ParseRenderSettingValue(*FindRenderSetting("direct"), "sometimes", "x"), InputError);
  EXPECT_EQ(ParseRenderSettingValue(*FindRenderSetting("occlusion-test"), "on", "x"),
            RenderSettingValue(true));
  JobRenderSettings s;
  SetRenderSetting(s, "structure", "grid", "--set structure");
  EXPECT_EQ(s.structure, PhotonMapKind::kGrid);
  SetRenderSetting(s, "direct", "mc", "x");
  EXPECT_EQ(s.direct, DirectLightMode::kMonteCarlo);
  SetRenderSetting(s, "direct", "auto", "x");
  EXPECT_FALSE(s.direct.has_value());
  EXPECT_THROW(SetRenderSetting(s, "photns", "1", "--set photns"), InputError);
}

// The map key holds exactly the rows that change a map and apply; and every row that changes
// what the maps are built from (MapsOptions) is marked so.
TEST(RenderSettingsTable, MapKeyCoversExactlyTheRowsThatChangeAMap) {
  for (const RenderSetting& row : RenderSettingsTable()) {
    SCOPED_TRACE(std::string(row.name));
    bool tested = false;
    for (const JobRenderSettings& base : Bases()) {
      JobRenderSettings changed = base;
      row.set(changed, OtherValue(row, base));
      if (row.applies && !(row.applies(base) && row.applies(changed))) continue;
      tested = true;
      EXPECT_EQ(changed.MapFingerprint() != base.MapFingerprint(), row.changes_map);
      if (MapsOptionsText(changed) != MapsOptionsText(base)) {
        EXPECT_TRUE(row.changes_map) << "changes the maps' options but not the key";
      }
    }
    EXPECT_TRUE(tested);
  }
  // A setting without effect leaves the key alone: S = 1 builds the maps of no splitting.
  JobRenderSettings s = Bases()[0];
  s.caustic_split = 1;
  const std::string key = s.MapFingerprint();
  s.caustic_split_method = CausticSplitMethod::kMetropolis;
  EXPECT_EQ(s.MapFingerprint(), key);
  s.direct.reset();
  EXPECT_THROW(s.MapFingerprint(), std::logic_error);  // auto must be resolved first
}

TEST(RenderSettingsTable, HeaderRecordsEveryRow) {
  JobRenderSettings s = Bases()[0];
  ImageMetadata meta;
  RecordRenderSettings(s, meta);
  std::set<std::string> keys;
  for (const auto& [key, value] : meta) keys.insert(key);
  std::set<std::string> want;
  for (const RenderSetting& row : RenderSettingsTable()) want.insert(SettingHeaderKey(row.name));
  EXPECT_EQ(keys, want);
  EXPECT_EQ(meta["settings.direct"], "mc");
  EXPECT_EQ(meta["settings.importance-min-probability"], "0.05");
  // The path tracer's header: the settings it reads.
  s.integrator = IntegratorKind::kPath;
  ImageMetadata path;
  RecordRenderSettings(s, path);
  EXPECT_EQ(path.size(), 2u);
  EXPECT_EQ(path["settings.integrator"], "path");
  EXPECT_EQ(path["settings.sampler"], "sobol");
}

TEST(RenderSettingsRules, CrossFieldRulesNameTheSetting) {
  const SettingNamer name = [](std::string_view n) { return "<" + std::string(n) + ">"; };
  JobRenderSettings s;
  EXPECT_NO_THROW(CheckRenderSettingRules(s, name));
  s.adaptive_k_min = 101;
  EXPECT_THAT([&] { CheckRenderSettingRules(s, name); },
              ::testing::ThrowsMessage<InputError>(HasSubstr("<adaptive-k-min>: must be <= k (100)")));
  s = {};
  s.irradiance_cache_error = 0.2f;
  EXPECT_THAT([&] { CheckRenderSettingRules(s, name); },
              ::testing::ThrowsMessage<InputError>(HasSubstr("<irradiance-cache-error>: caches")));
  s = {};
  s.caustic_split = 256;
  s.photons = 2000000;
  EXPECT_THROW(CheckRenderSettingRules(s, name), LimitError);
  s.integrator = IntegratorKind::kPath;  // the path tracer reads none of them
  EXPECT_NO_THROW(CheckRenderSettingRules(s, name));
  EXPECT_THROW(CheckRadiancePartsApart(s, "part"), InputError);
}

TEST(RenderSettingsRules, SettingsThatDoNotApplyAreFound) {
  JobRenderSettings s;
  s.integrator = IntegratorKind::kPath;
  std::vector<UnusedSetting> unused = UnusedSettings(s, {"photons", "sampler"});
  ASSERT_EQ(unused.size(), 1u);
  EXPECT_EQ(unused[0].name, "photons");
  EXPECT_THAT(unused[0].reason, HasSubstr("photon-map integrator only"));
  s.integrator = IntegratorKind::kPhotonMap;
  unused = UnusedSettings(s, {"photons", "caustic-split-method", "importons"});
  ASSERT_EQ(unused.size(), 2u);
  EXPECT_THAT(unused[0].reason, HasSubstr("caustic-split > 1"));
  EXPECT_THAT(unused[1].reason, HasSubstr("importance != off"));
  s.direct = DirectLightMode::kNone;
  EXPECT_EQ(UnusedSettings(s, {"shadow-rays"}).size(), 1u);
  EXPECT_EQ(NonDefaultSettings(s), std::vector<std::string>{"direct"});
}

}  // namespace
}  // namespace pf
