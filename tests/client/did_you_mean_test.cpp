#include "client/did_you_mean.h"

#include <gtest/gtest.h>

namespace pf {
namespace {

TEST(EditDistance, CountsInsertionsDeletionsAndSubstitutions) {
  EXPECT_EQ(EditDistance("", ""), 0);
  EXPECT_EQ(EditDistance("render", "render"), 0);
  EXPECT_EQ(EditDistance("rendr", "render"), 1);          // insertion
  EXPECT_EQ(EditDistance("--photonss", "--photons"), 1);  // deletion
  EXPECT_EQ(EditDistance("kitten", "sitting"), 3);
  EXPECT_EQ(EditDistance("", "abc"), 3);
  EXPECT_EQ(EditDistance("abc", ""), 3);
}

TEST(ClosestName, PicksTheNearestWithinAThirdOfTheWord) {
  const std::vector<std::string> names = {"render", "submit", "watch", "merge"};
  EXPECT_EQ(ClosestName("rendr", names), "render");
  EXPECT_EQ(ClosestName("mrege", names), std::nullopt);  // two substitutions in five letters: too far
  EXPECT_EQ(ClosestName("submti", names), "submit");
  EXPECT_EQ(ClosestName("frobnicate", names), std::nullopt);
  EXPECT_EQ(ClosestName("x", names), std::nullopt);
}

TEST(DidYouMean, NamesTheSubcommandOrOptionMeant) {
  CLI::App app;
  app.require_subcommand(1);
  app.fallthrough();
  int photons = 0;
  app.add_subcommand("render")->add_option("--photons", photons);
  app.add_subcommand("submit");
  EXPECT_THROW(app.parse(std::vector<std::string>{"rendr"}), CLI::ParseError);
  EXPECT_EQ(DidYouMean(app), std::vector<std::string>{"'rendr': did you mean 'render'?"});

  CLI::App app2;
  app2.fallthrough();
  app2.add_subcommand("render")->add_option("--photons", photons);
  // CLI11 parses a reversed vector: the last element is the first argument.
  EXPECT_THROW(app2.parse(std::vector<std::string>{"10", "--photon", "render"}), CLI::ParseError);
  EXPECT_EQ(DidYouMean(app2), std::vector<std::string>{"'--photon': did you mean '--photons'?"});
}

}  // namespace
}  // namespace pf
