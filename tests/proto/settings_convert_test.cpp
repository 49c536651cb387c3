// The proto conversion covers exactly the settings table: every field of RenderSettings and
// PhotonMapSettings is a row and every row a field, every enum value a choice, and every row's
// value survives the wire.

#include <gtest/gtest.h>

#include <set>
#include <string>

#include "common/render/render_settings_rules.h"
#include "common/render/render_settings_table.h"
#include "proto/convert.h"

namespace pf {
namespace {
namespace v1 = photonfarm::v1;
namespace gp = google::protobuf;

std::string Kebab(std::string name) {
  for (char& c : name) c = c == '_' ? '-' : c;
  return name;
}

TEST(SettingsConvert, WireFieldsAreExactlyTheTable) {
  std::set<std::string> fields;
  for (const gp::Descriptor* d : {v1::RenderSettings::descriptor(), v1::PhotonMapSettings::descriptor()})
    for (int i = 0; i < d->field_count(); ++i) {
      const gp::FieldDescriptor* f = d->field(i);
      if (f->message_type() == v1::PhotonMapSettings::descriptor()) continue;  // RenderSettings.photon_map
      EXPECT_TRUE(fields.insert(Kebab(f->name())).second) << f->name();
      const RenderSetting* row = FindRenderSetting(Kebab(f->name()));
      ASSERT_NE(row, nullptr) << f->full_name() << " has no row in the settings table";
      EXPECT_EQ(d == v1::PhotonMapSettings::descriptor(), row->PhotonMapOnly()) << f->name();
      if (const gp::EnumDescriptor* e = f->enum_type()) {
        EXPECT_EQ(size_t(e->value_count() - 1), row->choices.size())
            << e->full_name() << ": every value but UNSPECIFIED is a choice";
      }
    }
  std::set<std::string> rows;
  for (const RenderSetting& row : RenderSettingsTable()) rows.insert(std::string(row.name));
  EXPECT_EQ(fields, rows);
}

// A photon-map job at the defaults (photons and k stated, as a job must).
v1::RenderSettings PhotonMapJob() {
  v1::RenderSettings s;
  SettingsToProto(JobRenderSettings{}, &s);
  return s;
}

// Each row at every other value of its own (each choice, a value inside the range) goes to the
// wire and back unchanged; the rules are satisfied by a base where every setting applies.
TEST(SettingsConvert, EveryRowRoundTrips) {
  JobRenderSettings base = SettingsFromProto(PhotonMapJob(), "s");
  base.local_pass_rays = 8;
  base.local_pass_lookup = LocalPassLookup::kPrecomputed;
  base.caustic_split = 4;
  base.importance = ImportanceMode::kOn;
  for (const RenderSetting& row : RenderSettingsTable()) {
    std::vector<RenderSettingValue> values;
    if (row.type == SettingType::kChoice)
      for (const SettingChoice& c : row.choices) values.emplace_back(std::string(c.name));
    else if (row.type == SettingType::kBool)
      values = {true, false};
    else if (row.type == SettingType::kInt)
      values = {int64_t(row.min == 0 ? 0 : row.min), int64_t(row.min + 1)};
    else
      values = {0.5, 0.25};
    for (const RenderSettingValue& v : values) {
      JobRenderSettings s = base;
      row.set(s, v);
      if (row.name == "site-occlusion-test") s.occlusion_test = false;
      if (row.name == "map-tracing" || row.name == "caustic-split-method")
        s.importance = ImportanceMode::kOff;
      v1::RenderSettings wire;
      SettingsToProto(s, &wire);
      const JobRenderSettings back = SettingsFromProto(wire, "s");
      EXPECT_EQ(row.get(back), v) << row.name << " = " << FormatRenderSettingValue(v);
      EXPECT_EQ(NonDefaultSettings(back), NonDefaultSettings(s)) << row.name;
    }
  }
}

// Proto3 cannot tell 0 from unset: a 0 outside the range is the default, except for what a job
// must state.
// The progressive schedule's α at its default is left unset by SettingsToProto, like every default,
// and written by WriteProgressiveAlpha, which progressive jobs and tasks get: an unset α in a stored
// job means the former default 2/3 (server/scheduling/recovery.cpp).
TEST(SettingsConvert, ProgressiveAlphaIsWrittenEvenAtItsDefault) {
  JobRenderSettings s;
  s.integrator = IntegratorKind::kPhotonMap;
  v1::RenderSettings wire;
  SettingsToProto(s, &wire);
  EXPECT_FALSE(wire.photon_map().has_progressive_alpha());
  WriteProgressiveAlpha(s, &wire);
  ASSERT_TRUE(wire.photon_map().has_progressive_alpha());
  EXPECT_EQ(wire.photon_map().progressive_alpha(), 0.5);
  EXPECT_EQ(SettingsFromProto(wire, "settings").progressive_alpha, 0.5);
  s.integrator = IntegratorKind::kPath;
  v1::RenderSettings path_wire;
  SettingsToProto(s, &path_wire);
  WriteProgressiveAlpha(s, &path_wire);
  EXPECT_FALSE(path_wire.has_photon_map()) << "the path tracer has no schedule";
}

TEST(SettingsConvert, UnsetFieldsAreTheDefaults) {
  v1::RenderSettings s = PhotonMapJob();
  s.mutable_photon_map()->clear_glossy_depth();
  s.mutable_photon_map()->clear_caustic_split();
  const JobRenderSettings core = SettingsFromProto(s, "s");
  EXPECT_EQ(core.caustic_split, 1u);  // 0 = off
  EXPECT_EQ(core.glossy_depth, 0);    // 0 is a value here (as before the table)
  EXPECT_EQ(core.shadow_rays, 16);    // optional, unset
  EXPECT_FALSE(core.direct.has_value());
  // A path job: photon-map fields absent are no error, and none is written back.
  v1::RenderSettings path;
  path.set_integrator(v1::INTEGRATOR_PATH);
  const JobRenderSettings p = SettingsFromProto(path, "s");
  v1::RenderSettings again;
  SettingsToProto(p, &again);
  EXPECT_FALSE(again.has_photon_map());
  EXPECT_EQ(again.SerializeAsString(), path.SerializeAsString());
}

}  // namespace
}  // namespace pf
