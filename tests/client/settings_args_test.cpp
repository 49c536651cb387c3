// pf's render settings from the command line, a settings file and a manifest
// (client/settings_args.h): every row of the table can be set with --set, later sources win,
// unknown names get a "did you mean", and a setting the render would ignore is refused.

#include "client/settings_args.h"

#include <gtest/gtest.h>

#include <filesystem>
#include <fstream>

#include "common/core/error.h"
#include "common/render/render_settings_table.h"

namespace pf {
namespace {

std::string ErrorOf(const SettingArgs& a, const std::string& integrator = "photonmap") {
  try {
    SettingsFromArgs(a, integrator);
  } catch (const InputError& e) {
    return e.what();
  }
  return "";
}

TEST(SettingArgs, EveryRowCanBeSetWithSet) {
  for (const RenderSetting& row : RenderSettingsTable()) {
    SettingArgs a;
    // A value to set: the second choice, true, 1 or 0.5.
    std::string text;
    if (row.type == SettingType::kChoice)
      text = std::string(row.choices[1].name);
    else if (row.type == SettingType::kBool)
      text = "true";
    else
      text = row.type == SettingType::kInt ? "1" : "0.5";
    a.set = {std::string(row.name) + "=" + text};
    if (row.name == "caustic-split-method") a.set.insert(a.set.begin(), "caustic-split=4");
    if (row.name == "site-occlusion-test" || row.name == "local-pass-lookup" ||
        row.name == "irradiance-cache-error")
      a.set.insert(a.set.begin(), {"local-pass-rays=4", "local-pass-lookup=precomputed"});
    if (row.name.rfind("importance-", 0) == 0 || row.name == "importons")
      a.set.insert(a.set.begin(), "importance=on");
    JobRenderSettings s;
    ASSERT_NO_THROW(s = SettingsFromArgs(a, "photonmap")) << row.name << ": " << ErrorOf(a);
    EXPECT_EQ(FormatRenderSettingValue(row.get(s)), text) << row.name;
  }
}

TEST(SettingArgs, LaterSourcesWinAndOldFlagsStillWork) {
  const std::filesystem::path file = std::filesystem::temp_directory_path() / "pf_settings_args_test.json";
  std::ofstream(file) << R"({"photons": 5000, "k": 30, "direct": "mc"})";
  SettingArgs a;
  a.manifest = {{"photons", "100", "m.json: settings.photons"}, {"glossy-depth", "3", "m.json"}};
  a.file = file.string();
  a.long_flags = {{"k", "40", "--k"}};
  a.set = {"k=50"};
  const JobRenderSettings s = SettingsFromArgs(a, "photonmap");
  EXPECT_EQ(s.photons, 5000u);  // the file over the manifest
  EXPECT_EQ(s.glossy_depth, 3);
  EXPECT_EQ(s.k, 50);  // --set over the old --k over the file
  EXPECT_EQ(s.direct, DirectLightMode::kMonteCarlo);
  std::filesystem::remove(file);

  SettingArgs cache;
  cache.irradiance_cache_flag = true;  // the old --irradiance-cache: Ward's a = 0.2
  cache.set = {"local-pass-rays=4"};
  EXPECT_FLOAT_EQ(SettingsFromArgs(cache, "photonmap").irradiance_cache_error, 0.2f);
}

TEST(SettingArgs, MistakesAreNamed) {
  SettingArgs a;
  a.set = {"photns=10"};
  EXPECT_NE(ErrorOf(a).find("--set photns: no setting is called 'photns' (did you mean 'photons'?)"),
            std::string::npos)
      << ErrorOf(a);
  a.set = {"k"};
  EXPECT_NE(ErrorOf(a).find("expected NAME=VALUE"), std::string::npos);
  a.set = {"k=0"};
  EXPECT_NE(ErrorOf(a).find("--set k: must be >= 1"), std::string::npos) << ErrorOf(a);
  // Settings the render would ignore: an error on the command line...
  a.set = {"photons=1000"};
  EXPECT_NE(ErrorOf(a, "path").find("--set photons: applies to the photon-map integrator only"),
            std::string::npos);
  a.set = {"caustic-split-method=metropolis"};
  EXPECT_NE(ErrorOf(a).find("applies only when caustic-split > 1"), std::string::npos);
  // ... while a manifest's suggestions for the other integrator are skipped.
  SettingArgs m;
  m.manifest = {{"photons", "1000", "m.json"}};
  EXPECT_EQ(ErrorOf(m, "path"), "");
}

}  // namespace
}  // namespace pf
