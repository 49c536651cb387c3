// Sizes and durations as typed on command lines (common/core/byte_size_text.h, duration_text.h).
#include <gtest/gtest.h>

#include "common/core/byte_size_text.h"
#include "common/core/duration_text.h"

namespace pf {
namespace {

TEST(ByteSizeText, BinaryUnitsAndPlainBytes) {
  EXPECT_EQ(ParseByteSizeText("0", "x"), 0u);
  EXPECT_EQ(ParseByteSizeText("1234", "x"), 1234u);
  EXPECT_EQ(ParseByteSizeText("64K", "x"), 64u * 1024);
  EXPECT_EQ(ParseByteSizeText("500M", "x"), 500ull << 20);
  EXPECT_EQ(ParseByteSizeText("500MB", "x"), 500ull << 20);
  EXPECT_EQ(ParseByteSizeText("2G", "x"), 2ull << 30);
  EXPECT_EQ(ParseByteSizeText("1.5g", "x"), 3ull << 29);
  EXPECT_EQ(ParseByteSizeText("1T", "x"), 1ull << 40);
}

TEST(ByteSizeText, AnythingElseIsRefusedNamingTheOption) {
  for (const char* bad : {"", "-1M", "2X", "M", "1MM", "nan", "inf", "1e30", "12 M"}) {
    SCOPED_TRACE(bad);
    try {
      ParseByteSizeText(bad, "--maps-quota");
      ADD_FAILURE() << "accepted";
    } catch (const InputError& e) {
      EXPECT_NE(std::string(e.what()).find("--maps-quota: '"), std::string::npos) << e.what();
    }
    EXPECT_FALSE(ByteSizeTextProblem(bad).empty());
  }
  EXPECT_TRUE(ByteSizeTextProblem("2G").empty());
}

TEST(DurationText, UnitsAndRefusals) {
  EXPECT_EQ(ParseDurationText("7d", "x"), 7 * 86400.0);
  EXPECT_EQ(ParseDurationText("90", "x"), 90.0);
  EXPECT_FALSE(DurationTextProblem("7w").empty());
}

}  // namespace
}  // namespace pf
