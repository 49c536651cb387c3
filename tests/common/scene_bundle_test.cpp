// Scene bundles: collection rule, content hash (stable, order-independent, content-sensitive),
// path rules (no escaping the bundle directory), write + load round trip.
#include "common/scene/scene_bundle.h"

#include <gmock/gmock.h>
#include <gtest/gtest.h>
#include <unistd.h>

#include <algorithm>
#include <fstream>

#include "common/core/error.h"
#include "tests/util/temp_dir.h"

namespace pf {
namespace {
namespace fs = std::filesystem;
using ::testing::HasSubstr;

// A one-quad MGF scene with a light, and an included file in a subfolder.
constexpr const char* kMainMgf =
    "# test scene\n"
    "m white =\n  c\n  rd .5\n"
    "v a =\n p 0 0 0\nv b =\n p 1 0 0\nv c =\n p 1 1 0\nv d =\n p 0 1 0\n"
    "f a b c d\n"
    "i parts/light.mgf\n";
constexpr const char* kLightMgf =
    "m lamp =\n  c\n  ed 10\n"
    "v e =\n p 0 0 2\nv f =\n p 0 1 2\nv g =\n p 1 1 2\nv h =\n p 1 0 2\n"
    "f e f g h\n";

class SceneBundleTest : public test_util::TempDirTest {
 protected:
  void SetUp() override { fs::create_directories(dir_ / "scene" / "parts"); }
  fs::path Write(const std::string& rel, const std::string& content) {
    return tmp_.Write("scene/" + rel, content);
  }
  SceneBundle Sample() {
    SceneBundle b;
    b.entry = "main.mgf";
    b.files = {{"main.mgf", kMainMgf}, {"parts/light.mgf", kLightMgf}};
    return b;
  }
};

TEST_F(SceneBundleTest, CollectTakesEveryFileBelowTheEntryFolder) {
  const fs::path entry = Write("main.mgf", kMainMgf);
  Write("parts/light.mgf", kLightMgf);
  Write("notes/readme.txt", "hello");
  Write("reference-256.exr", "rendered output");  // images are outputs: left out
  Write("previews/view.PNG", "rendered output");
  const SceneBundle b = CollectBundle(entry);
  EXPECT_EQ(b.entry, "main.mgf");
  std::vector<std::string> paths;
  for (const auto& [p, c] : b.files) paths.push_back(p);
  EXPECT_EQ(paths, (std::vector<std::string>{"main.mgf", "notes/readme.txt", "parts/light.mgf"}));
  EXPECT_EQ(b.files[2].second, kLightMgf);
}

TEST_F(SceneBundleTest, CollectRejectsMissingEntry) {
  EXPECT_THROW(CollectBundle(dir_ / "scene" / "nope.mgf"), InputError);
}

TEST_F(SceneBundleTest, HashIsStableHexSha256) {
  const std::string h = BundleHash(Sample());
  EXPECT_EQ(h.size(), 64u);
  EXPECT_TRUE(std::all_of(h.begin(), h.end(), [](char c) { return std::isxdigit(c) && !std::isupper(c); }));
  EXPECT_EQ(h, BundleHash(Sample()));
  // Pinned: the layout is a wire contract (workers and clients compute the same hash).
  SceneBundle tiny;
  tiny.entry = "a";
  tiny.files = {{"a", "x"}};
  // = hashlib.sha256(b"photonfarm-bundle-v1\n" + le64(1) + b"a" + le64(1) + le64(1) + b"a" + le64(1) + b"x")
  EXPECT_EQ(BundleHash(tiny), "1ece5b9844724def16a7e32409c478afc249fbd8dccbe743919d5e5c230d553b");
  SceneBundle empty_content = tiny;
  empty_content.files[0].second.clear();
  EXPECT_NE(BundleHash(tiny), BundleHash(empty_content));
}

TEST_F(SceneBundleTest, HashDoesNotDependOnListingOrder) {
  SceneBundle a = Sample();
  SceneBundle b = Sample();
  std::reverse(b.files.begin(), b.files.end());
  EXPECT_EQ(BundleHash(a), BundleHash(b));
}

TEST_F(SceneBundleTest, HashChangesWithContentPathsAndEntry) {
  const std::string base = BundleHash(Sample());
  SceneBundle content = Sample();
  content.files[1].second += " ";
  EXPECT_NE(BundleHash(content), base);
  SceneBundle renamed = Sample();
  renamed.files[1].first = "parts/light2.mgf";
  EXPECT_NE(BundleHash(renamed), base);
  SceneBundle entry = Sample();
  entry.entry = "parts/light.mgf";
  EXPECT_NE(BundleHash(entry), base);
  // Length prefixes: moving bytes between path and content changes the hash.
  SceneBundle x, y;
  x.entry = y.entry = "ab";
  x.files = {{"ab", "c"}};
  y.files = {{"ab", "c"}, {"d", ""}};
  EXPECT_NE(BundleHash(x), BundleHash(y));
}

TEST_F(SceneBundleTest, PathTraversalAndBadNamesAreRejected) {
  const std::vector<std::pair<std::string, std::string>> bad = {
      {"../evil.mgf", "'..' component"},
      {"parts/../../evil.mgf", "'..' component"},
      {"/etc/passwd", "absolute path"},
      {"", "empty path"},
      {"a//b.mgf", "empty path component"},
      {"./a.mgf", "'.' component"},
      {"a\\b.mgf", "backslash"},
      {"main.mgf", "duplicate path"},
  };
  for (const auto& [path, reason] : bad) {
    SceneBundle b = Sample();
    b.files.emplace_back(path, "x");
    try {
      WriteBundle(b, dir_ / "out");
      ADD_FAILURE() << "accepted " << path;
    } catch (const InputError& e) {
      EXPECT_THAT(e.what(), HasSubstr("bundle.files[2].path '" + path + "'")) << path;
      EXPECT_THAT(e.what(), HasSubstr(reason)) << path;
    }
  }
  EXPECT_FALSE(fs::exists(dir_ / "evil.mgf"));
  SceneBundle no_entry = Sample();
  no_entry.entry = "missing.mgf";
  EXPECT_THROW(ValidateBundle(no_entry), InputError);
  EXPECT_THROW(LoadBundle(dir_, "../scene/main.mgf"), InputError);
}

TEST_F(SceneBundleTest, SizeLimitIsNamed) {
  SceneBundle big = Sample();
  big.files.emplace_back("big.bin", std::string(kMaxBundleBytes, 'x'));
  EXPECT_THAT([&] { (void)ValidateBundle(big); }, ::testing::ThrowsMessage<InputError>(HasSubstr("64 MiB")))
      << "accepted an over-limit bundle";
}

TEST_F(SceneBundleTest, WriteThenLoadRoundTrip) {
  const fs::path out = dir_ / "stored";
  WriteBundle(Sample(), out);
  const SceneDescription scene = LoadBundle(out, "main.mgf");
  EXPECT_EQ(scene.NumTriangles(), 4u);
  EXPECT_EQ(scene.num_lights, 1u);
  // Collecting the written folder gives back the same bundle and hash.
  EXPECT_EQ(BundleHash(CollectBundle(out / "main.mgf")), BundleHash(Sample()));
}

TEST_F(SceneBundleTest, LoaderErrorsNameBundleRelativeFileAndLine) {
  SceneBundle b = Sample();
  b.files[1].second = "m lamp =\n  c\n  ed 10\nf nowhere1 nowhere2 nowhere3\n";
  const fs::path out = dir_ / "stored";
  WriteBundle(b, out);
  try {
    LoadBundle(out, "main.mgf");
    ADD_FAILURE() << "loaded a broken scene";
  } catch (const InputError& e) {
    EXPECT_THAT(e.what(), HasSubstr("parts/light.mgf:4"));
    EXPECT_THAT(std::string(e.what()), ::testing::Not(HasSubstr(out.string())));
  }
}

}  // namespace
}  // namespace pf
