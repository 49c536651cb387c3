// docs/settings.md is the output of `pf settings --markdown` (client/settings_command.cpp), and
// holds every setting of the table.

#include <gtest/gtest.h>

#include <fstream>
#include <sstream>

#include "client/commands.h"
#include "common/render/render_settings_table.h"

namespace pf {
namespace {

TEST(SettingsCommand, ReferencePageIsTheGeneratedOne) {
  std::ifstream in(std::string(PF_SOURCE_DIR) + "/docs/settings.md");
  ASSERT_TRUE(in) << "docs/settings.md missing";
  std::stringstream committed;
  committed << in.rdbuf();
  EXPECT_EQ(committed.str(), SettingsReferencePage())
      << "docs/settings.md is stale: regenerate it with pf settings --markdown > docs/settings.md";
  for (const RenderSetting& row : RenderSettingsTable())
    EXPECT_NE(committed.str().find("| `" + std::string(row.name) + "` |"), std::string::npos) << row.name;
}

}  // namespace
}  // namespace pf
