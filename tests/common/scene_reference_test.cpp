// Scene references stay inside the scene's root (scene_reference.h): MGF `i`, manifest
// "geometry" and OBJ `mtllib` that are absolute, escape with "..", or leave through a symbolic
// link are InputErrors naming file:line; nothing of the outside file is read or echoed, and the
// answer for a missing outside file is the same as for an existing one (no existence oracle).
#include "common/scene/scene_reference.h"

#include <gmock/gmock.h>
#include <gtest/gtest.h>
#include <unistd.h>

#include <fstream>

#include "common/core/error.h"
#include "common/scene/scene_bundle.h"
#include "common/scene/scene_loader.h"
#include "tests/util/temp_dir.h"

namespace pf {
namespace {
namespace fs = std::filesystem;
using ::testing::HasSubstr;
using ::testing::Not;

// It emits (LoadScene refuses a scene without light), in 12 lines like a plain quad's.
constexpr const char* kQuadMgf =
    "m white =\n  c\n  ed 10\n"
    "v a =\n p 0 0 0\nv b =\n p 1 0 0\nv c =\n p 1 1 0\nv d =\n p 0 1 0\n"
    "f a b c d\n";
// An outside file whose words would show up in "unknown entity" warnings if it were read.
constexpr const char* kSecret = "SECRETWORD one two\nOTHERSECRET three\n";
constexpr const char* kQuadObj = "v 0 0 0\nv 1 0 0\nv 1 1 0\nf 1 2 3\n";

class SceneReferenceTest : public test_util::TempDirTest {
 protected:
  void SetUp() override {
    fs::create_directories(dir_ / "scene");
    Write("outside/secret.mgf", kSecret);
    Write("outside/secret.obj", kQuadObj);
    Write("outside/secret.mtl", "newmtl SECRETMAT\nKd 1 0 0\n");
  }
  fs::path Write(const std::string& rel, const std::string& content) { return tmp_.Write(rel, content); }
  // The message of the InputError LoadScene throws ("" if it loads).
  std::string LoadError(const fs::path& entry) {
    try {
      LoadScene(entry);
    } catch (const InputError& e) {
      return e.what();
    }
    return "";
  }
  // `absolute`: the reference itself is an absolute path, echoed as written (the writer's
  // own text); otherwise nothing of the outside folder may appear.
  std::string ExpectRefused(const fs::path& entry, const std::string& where, bool absolute = false) {
    const std::string msg = LoadError(entry);
    EXPECT_THAT(msg, HasSubstr(where));
    EXPECT_THAT(msg, Not(HasSubstr("SECRET")));
    if (!absolute) {
      EXPECT_THAT(msg, Not(HasSubstr((dir_ / "outside").string())));
    }
    return msg;
  }
};

TEST_F(SceneReferenceTest, MgfIncludeOutsideTheSceneFolderIsRefused) {
  ExpectRefused(Write("scene/a.mgf", std::string(kQuadMgf) + "i ../outside/secret.mgf\n"),
                "a.mgf:13: include '../outside/secret.mgf' resolves outside the scene folder");
  ExpectRefused(Write("scene/b.mgf", std::string("i sub/../../outside/secret.mgf\n")), "b.mgf:1:");
  ExpectRefused(Write("scene/c.mgf", "i " + (dir_ / "outside/secret.mgf").string() + "\n"),
                "c.mgf:1: include", true);
  // Inside the folder, includes (also up and down again) still work.
  Write("scene/parts/quad.mgf", kQuadMgf);
  Write("scene/d.mgf", "i parts/../parts/quad.mgf\n");
  EXPECT_EQ(LoadError(dir_ / "scene/d.mgf"), "");
}

TEST_F(SceneReferenceTest, MissingAndExistingOutsideFilesGetTheSameAnswer) {
  const std::string existing = ExpectRefused(Write("scene/a.mgf", "i ../outside/secret.mgf\n"), "a.mgf:1:");
  const std::string missing = ExpectRefused(Write("scene/a.mgf", "i ../outside/nothere.mgf\n"), "a.mgf:1:");
  EXPECT_EQ(missing.substr(missing.find("resolves")), existing.substr(existing.find("resolves")));
  const std::string obj_existing = ExpectRefused(
      Write("scene/m.obj", std::string("mtllib ../outside/secret.mtl\n") + kQuadObj), "m.obj:1:");
  const std::string obj_missing =
      ExpectRefused(Write("scene/m.obj", std::string("mtllib ../outside/none.mtl\n") + kQuadObj), "m.obj:1:");
  EXPECT_EQ(obj_missing.substr(obj_missing.find("resolves")),
            obj_existing.substr(obj_existing.find("resolves")));
}

TEST_F(SceneReferenceTest, ManifestGeometryOutsideTheSceneFolderIsRefused) {
  ExpectRefused(Write("scene/a.json", "{\n  \"geometry\": \"../outside/secret.obj\"\n}\n"),
                "a.json:2: key 'geometry': '../outside/secret.obj' resolves outside");
  ExpectRefused(Write("scene/b.json", "{\"geometry\": \"" + (dir_ / "outside/secret.obj").string() + "\"}"),
                "b.json:1: key 'geometry'", true);
  ExpectRefused(Write("scene/c.json", R"({"geometry": "/nonexistent/x.obj"})"), "is an absolute path");
  Write("scene/geo/quad.obj", kQuadObj);
  Write("scene/d.json",
        R"({"geometry": "geo/quad.obj", "lights": [{"type": "point", "position": [0, 0, 1]}]})");
  EXPECT_EQ(LoadError(dir_ / "scene/d.json"), "");
}

TEST_F(SceneReferenceTest, ObjMtllibOutsideTheSceneFolderIsRefused) {
  ExpectRefused(Write("scene/a.obj", std::string("# x\nmtllib ../outside/secret.mtl\n") + kQuadObj),
                "a.obj:2: mtllib '../outside/secret.mtl' resolves outside the scene folder");
  ExpectRefused(Write("scene/b.obj", "mtllib " + (dir_ / "outside/secret.mtl").string() + "\n" + kQuadObj),
                "b.obj:1: mtllib", true);
  // A manifest in the scene folder whose OBJ lives in a subfolder may refer to an MTL next to
  // the manifest (still inside the root).
  Write("scene/shared.mtl", "newmtl red\nKd 1 0 0\n");
  Write("scene/geo/q.obj", std::string("mtllib ../shared.mtl\nusemtl red\n") + kQuadObj);
  Write("scene/q.json", R"({"geometry": "geo/q.obj", "lights": [{"type": "point", "position": [0, 0, 1]}]})");
  const SceneDescription s = LoadScene(dir_ / "scene/q.json");
  ASSERT_EQ(s.materials.size(), 1u);
  EXPECT_EQ(s.materials[0].name, "red");
}

TEST_F(SceneReferenceTest, SymbolicLinksLeavingTheSceneFolderAreRefused) {
  fs::create_symlink(dir_ / "outside", dir_ / "scene" / "linkdir");
  fs::create_symlink(dir_ / "outside" / "secret.mgf", dir_ / "scene" / "link.mgf");
  fs::create_symlink(dir_ / "outside" / "nothere.mgf", dir_ / "scene" / "dangling.mgf");
  const std::string a = ExpectRefused(Write("scene/a.mgf", "i linkdir/secret.mgf\n"), "a.mgf:1: include");
  EXPECT_THAT(a, HasSubstr("resolves outside"));
  ExpectRefused(Write("scene/b.mgf", "i link.mgf\n"), "b.mgf:1: include 'link.mgf' resolves outside");
  ExpectRefused(Write("scene/c.mgf", "i dangling.mgf\n"), "c.mgf:1: include 'dangling.mgf' resolves outside");
  ExpectRefused(Write("scene/d.json", R"({"geometry": "linkdir/secret.obj"})"), "d.json:1: key 'geometry'");
  // A link that stays inside is fine.
  Write("scene/real/quad.mgf", kQuadMgf);
  fs::create_symlink(dir_ / "scene" / "real" / "quad.mgf", dir_ / "scene" / "inlink.mgf");
  Write("scene/e.mgf", "i inlink.mgf\n");
  EXPECT_EQ(LoadError(dir_ / "scene/e.mgf"), "");
}

TEST_F(SceneReferenceTest, ControlCharactersAreEscapedInMessages) {
  EXPECT_EQ(QuoteReference("a\nb\x1b[31m"), "'a\\nb\\x1b[31m'");
  EXPECT_EQ(QuoteReference(std::string(300, 'x')), "'" + std::string(200, 'x') + "...'");
  fs::path resolved;
  EXPECT_THAT(SceneReferenceProblem(dir_, dir_, "a\x1b.mgf", &resolved), HasSubstr("control character"));
  EXPECT_EQ(SceneReferenceProblem(dir_, dir_ / "sub", "../x.mgf", &resolved), "");
  EXPECT_EQ(resolved, (dir_ / "x.mgf").lexically_normal());
}

// On the farm the root is the bundle directory: a bundle's entry in a subfolder may include
// files elsewhere in the bundle, but nothing beside the bundle directory.
TEST_F(SceneReferenceTest, BundleRootIsTheBundleDirectory) {
  SceneBundle ok;
  ok.entry = "scenes/main.mgf";
  ok.files = {{"scenes/main.mgf", "i ../parts/quad.mgf\n"}, {"parts/quad.mgf", kQuadMgf}};
  WriteBundle(ok, dir_ / "bundle");
  EXPECT_EQ(LoadBundle(dir_ / "bundle", ok.entry).NumTriangles(), 2u);

  SceneBundle bad;
  bad.entry = "main.mgf";
  bad.files = {{"main.mgf", "i ../outside/secret.mgf\n"}};
  WriteBundle(bad, dir_ / "bundle2");
  Write("bundle2/../outside/secret.mgf", kSecret);
  try {
    LoadBundle(dir_ / "bundle2", "main.mgf");
    ADD_FAILURE() << "loaded";
  } catch (const InputError& e) {
    EXPECT_EQ(std::string(e.what()), "main.mgf:1: include '../outside/secret.mgf' " +
                                         std::string("resolves outside the scene folder (references "
                                                     "must stay inside the folder of the scene's "
                                                     "entry file)"));
  }
}

TEST(BundlePaths, AFileCannotAlsoBeAFolder) {
  SceneBundle b;
  b.entry = "main.mgf";
  b.files = {{"main.mgf", kQuadMgf}, {"a", "x"}, {"a/b", "y"}};
  try {
    ValidateBundle(b);
    ADD_FAILURE() << "accepted";
  } catch (const InputError& e) {
    EXPECT_THAT(std::string(e.what()), HasSubstr("bundle.files[2].path 'a/b': 'a' is also a file"));
  }
  b.files = {{"main.mgf", kQuadMgf}, {"a\n\x1b[2J", "x"}};
  try {
    ValidateBundle(b);
    ADD_FAILURE() << "accepted";
  } catch (const InputError& e) {
    EXPECT_THAT(std::string(e.what()), HasSubstr("'a\\n\\x1b[2J': path contains a control character"));
  }
}

// An OBJ with a NaN vertex was accepted (tinyobjloader reads "nan" as a number).
TEST_F(SceneReferenceTest, ObjVerticesMustBeFiniteNumbers) {
  for (const char* bad : {"nan", "inf", "-inf", "1e999", "1e39", "0x1p3", "abc"}) {
    const fs::path p = Write("scene/bad.obj", std::string("v 0 0 0\nv 1 0 ") + bad + "\nv 0 1 0\nf 1 2 3\n");
    EXPECT_THAT(LoadError(p),
                HasSubstr("bad.obj:2: v coordinate '" + std::string(bad) + "' is not a finite number"))
        << bad;
  }
  const fs::path n = Write("scene/badn.obj", "v 0 0 0\nv 1 0 0\nv 0 1 0\nvn 0 nan 1\nf 1//1 2//1 3//1\n");
  EXPECT_THAT(LoadError(n), HasSubstr("badn.obj:4: vn coordinate 'nan'"));
  // Its vertices are fine: only refused for having no light (LoadScene's last check).
  EXPECT_THAT(LoadError(Write("scene/ok.obj", "v 0 0 0\nv 1.5e2 -0 0\nv 0 1 +0.5\nf 1 2 3\n")),
              HasSubstr("ok.obj: the scene has no light"));
}

}  // namespace
}  // namespace pf
