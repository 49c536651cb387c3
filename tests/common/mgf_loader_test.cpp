// Tests of the MGF 2.0 loader (common/scene/mgf_loader.h): every shipped scene loads, malformed
// input fails with file:line and a reason, and the geometry, colour and emission conversions are
// checked against analytic values.

#include "common/scene/mgf_loader.h"
#include "common/scene/mgf_color.h"

#include <gmock/gmock.h>
#include <gtest/gtest.h>
#include <spdlog/spdlog.h>

#include <algorithm>
#include <chrono>
#include <cmath>
#include <cstdio>
#include <filesystem>
#include <fstream>
#include <map>
#include <numbers>
#include <set>
#include <string>
#include <vector>

#include "common/core/error.h"
#include "common/core/math.h"
#include "tests/util/temp_dir.h"

namespace pf {
namespace {

namespace fs = std::filesystem;

constexpr double kPi = std::numbers::pi;

// ---- helpers -----------------------------------------------------------------------------------

SceneDescription Load(const std::string& text, const MgfOptions& options = {}) {
  return LoadMgfFromString(text, "test.mgf", options);
}

// Vertex i in world coordinates (a scene far from the origin is stored relative to s.origin,
// scene_frame.h).
Vec3d P(const SceneDescription& s, uint32_t i) {
  return Vec3d(s.positions[i]) + s.origin;
}

// The bounds in world coordinates.
std::pair<Vec3d, Vec3d> WorldBoundsOf(const SceneDescription& s) {
  const Bounds3 b = s.ComputeBounds();
  return {Vec3d(b.lo) + s.origin, Vec3d(b.hi) + s.origin};
}

// Twice-area vector (right-hand rule) of triangle t.
Vec3d AreaVector(const SceneDescription& s, size_t t) {
  const auto& tri = s.triangles[t];
  return Cross(P(s, tri[1]) - P(s, tri[0]), P(s, tri[2]) - P(s, tri[0]));
}

double TotalArea(const SceneDescription& s) {
  double a = 0;
  for (size_t t = 0; t < s.triangles.size(); ++t) a += 0.5 * Length(AreaVector(s, t));
  return a;
}

double EmitterArea(const SceneDescription& s) {
  double a = 0;
  for (size_t t = 0; t < s.triangles.size(); ++t) {
    if (s.triangle_light[t] != kNoLight) a += 0.5 * Length(AreaVector(s, t));
  }
  return a;
}

// Signed volume by the divergence theorem: positive iff a closed mesh faces outwards.
double SignedVolume(const SceneDescription& s) {
  double v = 0;
  for (const auto& tri : s.triangles) {
    v += Dot(P(s, tri[0]), Cross(P(s, tri[1]), P(s, tri[2]))) / 6.0;
  }
  return v;
}

// Σ area vectors: zero for a closed mesh.
Vec3d AreaVectorSum(const SceneDescription& s) {
  Vec3d sum;
  for (size_t t = 0; t < s.triangles.size(); ++t) sum += AreaVector(s, t) * 0.5;
  return sum;
}

Vec3d Centroid(const SceneDescription& s) {
  Vec3d c;
  for (const Vec3& p : s.positions) c += Vec3d(p);
  return c / static_cast<double>(s.positions.size()) + s.origin;
}

void ExpectNear(const Vec3d& a, const Vec3d& b, double tol) {
  EXPECT_NEAR(a.x, b.x, tol);
  EXPECT_NEAR(a.y, b.y, tol);
  EXPECT_NEAR(a.z, b.z, tol);
}

// The InputError that LoadMgf throws (and a test failure if it loads).
InputError MgfError(const fs::path& path, const MgfOptions& options = {}) {
  try {
    LoadMgf(path, options);
  } catch (const InputError& e) {
    return e;
  }
  ADD_FAILURE() << path << " loaded";
  return InputError(path.string() + " loaded");
}
std::string MgfErrorReason(const fs::path& path, const MgfOptions& options = {}) {
  return MgfError(path, options).reason();
}

// A temporary directory removed at the end of the test.
class TempDir : public test_util::TempDir {
 public:
  TempDir() : test_util::TempDir("pf_mgf_test") {}
};

// The MGF spec's unit cube example: the base face cv0..cv3 looks down -z (a prism of it extruded
// by 1 to +z is the unit cube).
const char* kCubeBase = "\nv cv0 =\n  p 0 0 0\nv cv1 =\n  p 0 1 0\nv cv2 =\n  p 1 1 0\nv cv3 =\n  p 1 0 0\n";

const char* kUnitSquare = R"(
v a =
  p 0 0 0
v b =
  p 1 0 0
v c =
  p 1 1 0
v d =
  p 0 1 0
)";

class QuietLog : public ::testing::Environment {
 public:
  void SetUp() override { spdlog::set_level(spdlog::level::err); }
};
const auto* const kQuiet = ::testing::AddGlobalTestEnvironment(new QuietLog);

// ---- 1. every shipped scene --------------------------------------------------------------------

// Files that cannot stand alone: they use colours/materials that the file including them
// defines first (hospital/structure.mgf includes Materials/*.mgf, then these). Each must fail
// with exactly this "undefined" error, so that the list is kept honest.
const std::map<std::string, std::string> kFragments = {
    {"OscarChavarro-rpkCpp/hospital/chair.mgf", "undefined colour 'Asphalt'"},
    {"OscarChavarro-rpkCpp/hospital/liftdeur.mgf", "undefined material 'rood'"},
    {"OscarChavarro-rpkCpp/hospital/shade.mgf", "undefined colour 'Dupont_Chip80'"},
    {"OscarChavarro-rpkCpp/hospital/stoeltje.mgf", "undefined colour 'PineWood'"},
    // Not a fragment: the file itself is wrong ("m gold" where only a colour "gold" exists).
    {"akaliutau-phy-engine/caustic.mgf", "caustic.mgf:170: undefined material 'gold'"},
};

// Top-level scenes and the number of light sources (emitting primitives) they must have,
// counted by hand from the files.
const std::map<std::string, uint32_t> kScenesWithLights = {
    {"NREL-Radiance/examp1.mgf", 2},  // one cyl lamp, arrayed twice (-a 2 -my)
    {"OscarChavarro-rpkCpp/examp1.mgf", 2},
    {"OscarChavarro-rpkCpp/office3/office.mgf", 3},  // 2 fluorescent faces + 1 sphere bulb
    {"StepanHrbek-LightsprintSDK/scene8.mgf", 4},    // four 1x1 m ceiling panels
    {"OscarChavarro-rpkCpp/corridor.mgf", 57},       // 19 + 10 + 18 + 10 arrayed panels
    {"OscarChavarro-rpkCpp/office1/graz.mgf", 8},
    {"OscarChavarro-rpkCpp/office2/office2.mgf", 1},
    {"OscarChavarro-rpkCpp/salon/classroom.mgf", 24},
    {"OscarChavarro-rpkCpp/soda.mgf", 5},
    {"OscarChavarro-rpkCpp/hospital/main.mgf", 44},
    {"OscarChavarro-rpkCpp/cube.mgf", 2},
    {"OscarChavarro-rpkCpp/floor_gloss.mgf", 1},
    {"akaliutau-phy-engine/cornell_box_glass.mgf", 2},
    {"akaliutau-phy-engine/simple.mgf", 1},
};
// Top-level scenes without emitters that must still produce geometry.
const std::set<std::string> kScenesWithoutLights = {"NREL-Radiance/blinds20c.mgf"};

TEST(MgfSharedScenes, EveryMgfFileLoads) {
  const fs::path root = PF_MGF_CORPUS_DIR;
  ASSERT_TRUE(fs::is_directory(root)) << root;
  std::vector<fs::path> files;
  for (const auto& e : fs::recursive_directory_iterator(root)) {
    if (e.is_regular_file() && e.path().extension() == ".mgf") files.push_back(e.path());
  }
  std::sort(files.begin(), files.end());
  ASSERT_GE(files.size(), 50u);

  std::printf("%-52s %9s %8s %6s %5s %5s\n", "file", "triangles", "emissive", "lights", "mats", "warn");
  std::set<std::string> seen;
  for (const fs::path& file : files) {
    const std::string rel = fs::relative(file, root).generic_string();
    seen.insert(rel);
    if (const auto it = kFragments.find(rel); it != kFragments.end()) {
      const InputError e = MgfError(file);
      EXPECT_NE(std::string(e.what()).find(it->second), std::string::npos) << e.what();
      std::printf("%-52s %s\n", rel.c_str(), "(fragment / broken, see kFragments)");
      continue;
    }
    SceneDescription s;
    try {
      s = LoadMgf(file);
    } catch (const InputError& e) {
      ADD_FAILURE() << rel << ": " << e.what();
      continue;
    }
    std::printf("%-52s %9zu %8zu %6u %5zu %5zu\n", rel.c_str(), s.NumTriangles(), s.NumEmissiveTriangles(),
                s.num_lights, s.materials.size(), s.warnings.size());
    // Consistency of the soup.
    ASSERT_EQ(s.triangle_material.size(), s.triangles.size());
    ASSERT_EQ(s.triangle_light.size(), s.triangles.size());
    ASSERT_TRUE(s.normals.empty() || s.normals.size() == s.positions.size());
    std::set<uint32_t> light_ids;
    for (size_t t = 0; t < s.triangles.size(); ++t) {
      for (uint32_t v : s.triangles[t]) ASSERT_LT(v, s.positions.size());
      ASSERT_LT(s.triangle_material[t], s.materials.size());
      const uint32_t l = s.triangle_light[t];
      ASSERT_EQ(l != kNoLight, s.materials[s.triangle_material[t]].IsEmissive()) << rel;
      if (l != kNoLight) light_ids.insert(l);
    }
    EXPECT_EQ(light_ids.size(), s.num_lights) << rel;  // ids are exactly 0..num_lights-1
    if (!light_ids.empty()) {
      EXPECT_EQ(*light_ids.rbegin(), s.num_lights - 1) << rel;
    }

    if (const auto it = kScenesWithLights.find(rel); it != kScenesWithLights.end()) {
      EXPECT_GT(s.NumTriangles(), 0u) << rel;
      EXPECT_EQ(s.num_lights, it->second) << rel;
    }
    if (kScenesWithoutLights.count(rel)) {
      EXPECT_GT(s.NumTriangles(), 0u) << rel;
      EXPECT_EQ(s.num_lights, 0u) << rel;
    }
    if (rel == "StepanHrbek-LightsprintSDK/scene8.mgf") {
      EXPECT_NEAR(EmitterArea(s), 4.0, 1e-4);  // four 1 m x 1 m panels at y = 2.8
      for (size_t t = 0; t < s.triangles.size(); ++t) {
        if (s.triangle_light[t] == kNoLight) continue;
        const Vec3d n = AreaVector(s, t);
        EXPECT_LT(n.y, 0.0) << "ceiling emitters face down";
        EXPECT_NEAR(s.positions[s.triangles[t][0]].y, 2.8f, 1e-5f);
      }
    }
  }
  for (const auto& [rel, lights] : kScenesWithLights) EXPECT_TRUE(seen.count(rel)) << rel;
  for (const auto& [rel, why] : kFragments) EXPECT_TRUE(seen.count(rel)) << rel;
}

// The two big scenes load whole (their load time is printed for the record; speed is a matter
// for benchmarks, not for a timed test on a shared machine).
TEST(MgfSharedScenes, LargeScenesLoad) {
  const fs::path root = PF_MGF_CORPUS_DIR;
  for (const char* rel :
       {"OscarChavarro-rpkCpp/office1/graz.mgf", "OscarChavarro-rpkCpp/salon/classroom.mgf"}) {
    const auto t0 = std::chrono::steady_clock::now();
    const SceneDescription s = LoadMgf(root / rel);
    const double seconds = std::chrono::duration<double>(std::chrono::steady_clock::now() - t0).count();
    EXPECT_GT(s.NumTriangles(), 5000u) << rel;
    std::printf("%s: %zu triangles in %.0f ms\n", rel, s.NumTriangles(), seconds * 1e3);
  }
}

// ---- 2. malformed input ------------------------------------------------------------------------

struct BadInput {
  const char* text;
  const char* where;   // exact "name:line" prefix of the message
  const char* reason;  // substring of the reason
};

TEST(MgfErrors, MalformedInputsReportFileLineAndReason) {
  const std::vector<BadInput> cases = {
      {"v a =\n p 1 x 3\n", "bad.mgf:2", "'x' is not a number"},
      {"v a =\n p 1 2\n", "bad.mgf:2", "p: expected 3 arguments"},
      {"v a =\n p 1 2 3 4\n", "bad.mgf:2", "p: expected 3 arguments"},
      {"v a =\n p nan 0 0\n", "bad.mgf:2", "'nan' is not a finite number"},
      {"v a =\n p 0 inf 0\n", "bad.mgf:2", "'inf' is not a finite number"},
      {"v a =\n p 0 0 1e999\n", "bad.mgf:2", "'1e999' is out of range"},
      {"v a =\n p 0 0 -infinity\n", "bad.mgf:2", "not a finite number"},
      {"v a =\n p 0 0 1.5.2\n", "bad.mgf:2", "is not a number"},
      {"f a b c\n", "bad.mgf:1", "undefined vertex 'a'"},
      {"m nosuch\n", "bad.mgf:1", "undefined material 'nosuch'"},
      {"c nosuch\n", "bad.mgf:1", "undefined colour 'nosuch'"},
      {"m x = nosuch\n", "bad.mgf:1", "undefined material 'nosuch'"},
      {"v x = nosuch\n", "bad.mgf:1", "undefined vertex 'nosuch'"},
      {"c a =\n cxy .3 .3\ncmix 1 a 2 nosuch\n", "bad.mgf:3", "undefined colour 'nosuch'"},
      {"m a b\n", "bad.mgf:1", "expected [id [= [template]]]"},
      {"\n\nxf\n", "bad.mgf:3", "'xf' end without a matching begin"},
      {"xf -t 1 0 0\nxf\nxf\n", "bad.mgf:3", "'xf' end without a matching begin"},
      {"# comment\nxf -t 1 0 0\n", "bad.mgf:2", "not ended before the end of the file"},
      {"xf -q 1\nxf\n", "bad.mgf:1", "unknown transform option '-q'"},
      {"xf -t 1 2\nxf\n", "bad.mgf:1", "needs 3 arguments"},
      {"xf -s 0\nxf\n", "bad.mgf:1", "scale factor must not be zero"},
      {"xf -a 0 -t 1 0 0\nxf\n", "bad.mgf:1", "-a count '0' must be in [1,"},
      {"xf -a 2.5 -t 1 0 0\nxf\n", "bad.mgf:1", "'2.5' is not an integer"},
      {"xf -a 100000 -a 100000\nxf\n", "bad.mgf:1", "array of more than"},
      {"o\n", "bad.mgf:1", "'o' ends an object that was not begun"},
      {"o a b\n", "bad.mgf:1", "at most one object name"},
      {"cxy .3\n", "bad.mgf:1", "cxy: expected 2 arguments"},
      {"cxy .8 .5\n", "bad.mgf:1", "outside the CIE diagram"},
      {"cxy -.1 .5\n", "bad.mgf:1", "outside the CIE diagram"},
      {"cspec 400 700 1\n", "bad.mgf:1", "at least 2 values"},
      {"cspec 700 400 1 1\n", "bad.mgf:1", "l_min must be less than l_max"},
      {"cspec 100 200 1 1\n", "bad.mgf:1", "no positive luminance"},
      {"cct -5\n", "bad.mgf:1", "temperature must be positive"},
      {"cmix 1\n", "bad.mgf:1", "pairs of weight and colour"},
      {"m x =\n rd 1.5\n", "bad.mgf:2", "must be in [0, 1]"},
      {"m x =\n rd -0.1\n", "bad.mgf:2", "must be in [0, 1]"},
      {"m x =\n rs .1 -1\n", "bad.mgf:2", "roughness must not be negative"},
      {"m x =\n ed -1\n", "bad.mgf:2", "emittance must not be negative"},
      {"m x =\n ir 0 0\n", "bad.mgf:2", "real index of refraction must be positive"},
      {"m x =\n ed 1e300\n", "bad.mgf:2", "emittance is out of range"},
      {"m x =\n rs .1 1e31\n", "bad.mgf:2", "roughness is out of range"},
      {"m x =\n ir 1e300 0\n", "bad.mgf:2", "index of refraction is out of range"},
      {"c x =\n cmix 1 x -1 x\n", "bad.mgf:2", "no positive luminance"},
      {"m x =\n sides 3\n", "bad.mgf:2", "sides: must be 1 or 2"},
      {"m x =\n sides\n", "bad.mgf:2", "sides: expected 1 argument"},
      {"v a =\n p 0 0 0\nf a a\n", "bad.mgf:3", "f: expected at least 3 vertex names"},
      {"v a =\n p 0 0 0\nsph a 0\n", "bad.mgf:3", "sph: radius must not be zero"},
      {"v a =\n p 0 0 0\nsph a\n", "bad.mgf:3", "sph: expected 2 arguments"},
      {"v a =\n p 0 0 0\nv b =\n p 0 0 1\ncyl a 0 b\n", "bad.mgf:5", "cyl: radius must not be zero"},
      {"v a =\n p 0 0 0\ncyl a 1 a\n", "bad.mgf:3", "cyl: the end points coincide"},
      {"v a =\n p 0 0 0\nv b =\n p 0 0 1\ncone a 1 b -1\n", "bad.mgf:5", "opposite signs"},
      {"v a =\n p 0 0 0\nv b =\n p 0 0 1\ncone a 0 b 0\n", "bad.mgf:5", "both radii are zero"},
      {"v a =\n p 0 0 0\nring a 0 1\n", "bad.mgf:3", "ring: centre vertex 'a' has no normal"},
      {"v a =\n p 0 0 0\n n 0 0 1\nring a -1 1\n", "bad.mgf:4", "inner radius must not be negative"},
      {"v a =\n p 0 0 0\n n 0 0 1\nring a 1 1\n", "bad.mgf:4", "must be greater than the inner"},
      {"v a =\n p 0 0 0\n n 0 0 1\ntorus a 2 1\n", "bad.mgf:4", "|outer radius| must be greater"},
      {"v a =\n p 0 0 0\n n 0 0 1\ntorus a -1 2\n", "bad.mgf:4", "must not be negative"},
      {"v a =\n p 0 0 0\n n 0 0 1\ntorus a 0 0\n", "bad.mgf:4", "outer radius must not be zero"},
      {"v a =\n p 0 0 0\nprism a a 1\n", "bad.mgf:3", "at least 3 vertex names and a length"},
      {"v a =\n p 0 0 0\nv b =\n p 1 0 0\nv c =\n p 0 1 0\nprism a b c 0\n", "bad.mgf:7",
       "length must not be zero"},
      {"v a =\n p 0 0 0\nfh a a - a a a\n", "bad.mgf:3", "every contour needs at least 3"},
      {"i\n", "bad.mgf:1", "i: expected a file name"},
      {"i does_not_exist_42.mgf\n", "bad.mgf:1", "cannot include 'does_not_exist_42.mgf'"},
      {"i /etc/passwd\n", "bad.mgf:1", "is absolute"},
      {"i inc\x01.mgf\n", "bad.mgf:1", "control character"},
      // Continuation: the error is reported at the entity's first line.
      {"\nv a =\n p 1 \\\n 2 \\\n zz\n", "bad.mgf:3", "'zz' is not a number"},
      // Huge but finite coordinates overflow once transformed.
      {"xf -s 1e300\nv a =\n p 1e300 0 0\nsph a 1\nxf\n", "bad.mgf:4", "out of range"},
      {"xf -s 1e300 -s 1e300\nxf\n", "bad.mgf:1", "transform overflows"},
  };
  for (const BadInput& c : cases) {
    SCOPED_TRACE(c.text);
    try {
      LoadMgfFromString(c.text, "bad.mgf");
      ADD_FAILURE() << "no error for: " << c.text;
    } catch (const InputError& e) {
      const std::string msg = e.what();
      EXPECT_EQ(msg.rfind(std::string(c.where) + ": ", 0), 0u) << msg;
      EXPECT_NE(msg.find(c.reason), std::string::npos) << msg;
      EXPECT_EQ(e.where().ToString(), c.where);
    }
  }
}

TEST(MgfErrors, BadOptionsAreRejected) {
  for (int segments : {-1, 0, 2, 1025, 1 << 30}) {
    MgfOptions o;
    o.curve_segments = segments;
    EXPECT_THROW(Load("", o), InputError) << segments;
  }
}

// The budgets (scene_budget.h) are checked on the expansion computed before execution, so the
// error names the array whose block multiplies past the budget.
TEST(MgfErrors, ResourceLimitsStopBlowUps) {
  const std::string sphere = "v c =\n p 0 0 0\n";
  {
    MgfOptions o;
    o.budget.max_triangles = 10'000;
    try {
      Load(sphere + "xf -a 1000 -t 1 0 0 -a 1000 -t 0 1 0\nsph c .1\nxf\n", o);
      ADD_FAILURE();
    } catch (const InputError& e) {
      // 10^6 spheres of 2·24·12 triangles.
      EXPECT_THAT(e.what(),
                  testing::HasSubstr("test.mgf:3: expands to up to 576000000 triangles, more than the "
                                     "budget of 10000 (SceneBudget::max_triangles"));
    }
  }
  {
    MgfOptions o;
    o.budget.max_entities = 1000;
    try {
      Load("xf -a 100000 -t 1 0 0\nv x =\n p 0 0 0\nxf\n", o);
      ADD_FAILURE();
    } catch (const InputError& e) {
      // The xf, then 10^5 times its three entities (the closing xf among them).
      EXPECT_THAT(e.what(), testing::HasSubstr("test.mgf:1: expands to 300001 entities, more than the budget "
                                               "of 1000 (SceneBudget::max_entities"));
    }
  }
  {
    // Arrayed includes of an empty file do no entity work but must still be bounded.
    TempDir dir;
    dir.Write("empty.mgf", "");
    MgfOptions o;
    o.budget.max_entities = 10'000;
    try {
      LoadMgfFromString("xf -a 100000 -t 1 0 0\ni empty.mgf -a 100000 -t 0 1 0\nxf\n",
                        (dir.path() / "arr.mgf").string(), o);
      ADD_FAILURE();
    } catch (const InputError& e) {
      EXPECT_THAT(e.what(),
                  testing::HasSubstr("arr.mgf:2: expands to 100001 entities, more than the budget of "
                                     "10000"));
    }
  }
  {
    // A face beyond any legal line length.
    std::string face = "v a =\n p 0 0 0\nv b =\n p 1 0 0\nv c =\n p 0 1 0\nf";
    for (int i = 0; i < 5500; ++i) face += " a b c";
    try {
      Load(face + "\n");
      ADD_FAILURE();
    } catch (const InputError& e) {
      EXPECT_NE(std::string(e.what()).find("test.mgf:7: f: more than 16384 vertices"), std::string::npos)
          << e.what();
    }
  }
  {
    std::string nested;
    for (int i = 0; i < 65; ++i) nested += "xf -t 1 0 0\n";
    try {
      Load(nested);
      ADD_FAILURE();
    } catch (const InputError& e) {
      EXPECT_NE(std::string(e.what()).find("test.mgf:65: transforms nested deeper than 64"),
                std::string::npos)
          << e.what();
    }
  }
}

// The array bomb of the hardening issue: 145 bytes in four files, `i -a 1000` three levels deep
// over a quad: 10^9 quads. Before, the interpreter ran until the triangle limit stopped it (16 s
// and 1.5 GB per load, docs/security.md); now the expansion is computed before anything is
// executed and the instance budget refuses it at the include whose array crosses it: no entity
// executed, no triangle emitted.
TEST(MgfBudgets, ArrayBombIsRefusedBeforeAnyWork) {
  TempDir dir;
  dir.Write("x.mgf", "v a =\n p 0 0 0\nv b =\n p 1 0 0\nv c =\n p 1 1 0\nv d =\n p 0 1 0\nf a b c d\n");
  dir.Write("y.mgf", "i x.mgf -a 1000 -t 0 0 1\n");
  dir.Write("z.mgf", "i y.mgf -a 1000 -t 0 1 0\n");
  const fs::path bomb = dir.Write("bomb.mgf", "i z.mgf -a 1000 -t 1 0 0\n");
  MgfLoadCounts counts;
  MgfOptions o;
  o.counts = &counts;
  try {
    LoadMgf(bomb, o);
    ADD_FAILURE() << "loaded";
  } catch (const InputError& e) {
    // z.mgf alone: 1000 instances of y.mgf, each with 1000 of its own.
    EXPECT_THAT(e.what(),
                testing::HasSubstr("z.mgf:1: expands to 1001000 array instances, more than the budget "
                                   "of 1000000 (SceneBudget::max_instances"));
  }
  EXPECT_EQ(counts.executed_entities, 0u);
  EXPECT_EQ(counts.emitted_triangles, 0u);
  // Without the instance budget the entity budget refuses it, at the top: 1 + 1000 × (1 + z.mgf's
  // 1 + 1000 × (1 + y.mgf's 1 + 1000 × (1 + 9))).
  o.budget.max_instances = uint64_t(1) << 40;
  try {
    LoadMgf(bomb, o);
    ADD_FAILURE() << "loaded";
  } catch (const InputError& e) {
    EXPECT_THAT(e.what(),
                testing::HasSubstr("bomb.mgf:1: expands to 10002002001 entities, more than the budget "
                                   "of 50000000 (SceneBudget::max_entities"));
  }
  EXPECT_EQ(counts.executed_entities, 0u);
}

// The expansion computed before execution counts entities exactly as the interpreter executes
// them, and bounds the triangles and vertices it emits: nested arrays over an include, and every
// shipped MGF scene (their counts are the docs/security.md table).
TEST(MgfBudgets, ExpansionCountsWhatExecutionDoes) {
  TempDir dir;
  dir.Write("c.mgf", "v c =\n p 0 0 0\nsph c .1\n");
  const std::string top =
      "v a =\n p 0 0 0\nv b =\n p 1 0 0\nv d =\n p 0 1 0\n"  // 6 entities
      "xf -a 3 -t 2 0 0\n"                                   // 1
      "i c.mgf -a 2 -t 0 2 0\n"                              // 3 × (1 + 2 × (1 + 3))
      "f a b d\n"                                            // 3 × 1
      "xf\n";                                                // 3 × 1
  MgfLoadCounts counts;
  MgfOptions o;
  o.counts = &counts;
  const SceneDescription s = LoadMgfFromString(top, (dir.path() / "top.mgf").string(), o);
  EXPECT_EQ(counts.expected.entities, 40u);
  EXPECT_EQ(counts.executed_entities, 40u);
  EXPECT_EQ(counts.expected.instances, 9u);  // 3 + 3 × 2
  // Bounds: a sphere 2·24·12 triangles and 13·24 vertices, the face 1 and 3; emitted: spheres of
  // 2·24·12 − 2·24 triangles (curved_primitives.h).
  EXPECT_EQ(counts.expected.triangles, 3u * (2 * 576 + 1));
  EXPECT_EQ(counts.expected.vertices, 3u * (2 * 312 + 3));
  EXPECT_EQ(counts.emitted_triangles, 3u * (2 * 528 + 1));
  EXPECT_EQ(s.NumTriangles(), counts.emitted_triangles);

  std::printf("%-28s %10s %10s %10s %10s\n", "scene", "entities", "instances", "triangles<=", "vertices<=");
  for (const auto& e : fs::directory_iterator(fs::path(PF_SOURCE_DIR) / "scenes")) {
    if (!e.is_directory()) continue;
    for (const auto& f : fs::directory_iterator(e.path())) {
      if (f.path().extension() != ".mgf") continue;
      const SceneDescription scene = LoadMgf(f.path(), o);
      EXPECT_EQ(counts.executed_entities, counts.expected.entities) << f.path();
      EXPECT_LE(counts.emitted_triangles, counts.expected.triangles) << f.path();
      EXPECT_LE(scene.positions.size(), counts.expected.vertices) << f.path();
      EXPECT_TRUE(SceneBudget{}.Exceeded(counts.expected).empty()) << f.path();
      std::printf("%-28s %10llu %10llu %10llu %10llu\n", f.path().filename().string().c_str(),
                  (unsigned long long)counts.expected.entities, (unsigned long long)counts.expected.instances,
                  (unsigned long long)counts.expected.triangles,
                  (unsigned long long)counts.expected.vertices);
    }
  }
}

// Coordinates far from the origin stay in double until the scene's frame is chosen
// (scene_frame.h): a quad written at 1e6 + decimals, directly and through `xf -t`, is stored
// relative to the centre of its double-precision bounds, each position the exact point minus that
// origin rounded once (world floats there are 6.25 cm apart); the same quad at the origin is
// stored in world floats, as before.
TEST(MgfFrame, FarCoordinatesAreStoredRelativeToTheirCentre) {
  const double x[] = {1000000.13, 1000001.87, 1000001.87, 1000000.13};
  const double y[] = {-2000000.27, -2000000.27, -1999999.61, -1999999.61};
  const double z = 3000000.39;
  std::string direct;
  for (int i = 0; i < 4; ++i) {
    char line[128];
    std::snprintf(line, sizeof line, "v v%d =\n p %.2f %.2f %.2f\n", i, x[i], y[i], z);
    direct += line;
  }
  direct += "f v0 v1 v2 v3\n";
  const std::string moved =
      "v v0 =\n p .13 -.27 .39\nv v1 =\n p 1.87 -.27 .39\nv v2 =\n p 1.87 .39 .39\nv v3 =\n p .13 .39 .39\n"
      "xf -t 1000000 -2000000 3000000\nf v0 v1 v2 v3\nxf\n";
  const Vec3d centre((x[0] + x[1]) / 2, (y[0] + y[2]) / 2, z);
  for (const std::string& text : {direct, moved}) {
    const SceneDescription s = Load(text);
    EXPECT_NEAR(s.origin.x, centre.x, 1e-9);
    EXPECT_NEAR(s.origin.y, centre.y, 1e-9);
    EXPECT_NEAR(s.origin.z, centre.z, 1e-9);
    ASSERT_EQ(s.positions.size(), 4u);
    std::set<std::pair<float, float>> corners;
    for (const Vec3& p : s.positions) {
      corners.insert({p.x, p.y});
      EXPECT_NEAR(p.z, 0.0f, 1e-6f);
    }
    // The quad's shape, 1.74 × 0.66 m, to float precision at its size.
    const std::set<std::pair<float, float>> expected = {
        {-0.87f, -0.33f}, {0.87f, -0.33f}, {0.87f, 0.33f}, {-0.87f, 0.33f}};
    for (const auto& [ex, ey] : expected) {
      bool found = false;
      for (const auto& [cx, cy] : corners)
        found = found || (std::fabs(cx - ex) < 1e-6f && std::fabs(cy - ey) < 1e-6f);
      EXPECT_TRUE(found) << ex << "," << ey;
    }
  }
  // Around the origin nothing moves: the floats are the world coordinates.
  const SceneDescription near =
      Load("v a =\n p .13 -.27 .39\nv b =\n p 1.87 -.27 .39\nv c =\n p 1.87 .39 .39\nf a b c\n");
  EXPECT_EQ(near.origin, Vec3d());
  EXPECT_EQ(near.positions[0], Vec3(0.13f, -0.27f, 0.39f));
}

TEST(MgfErrors, IncludeCyclesDepthMissingAndRoot) {
  TempDir dir;
  dir.Write("a.mgf", "# a\ni sub/b.mgf\n");
  dir.Write("sub/b.mgf", "\ni ../a.mgf\n");
  {
    const InputError e = MgfError(dir.path() / "a.mgf");
    // Reported where the cycle closes: in b.mgf, line 2.
    EXPECT_EQ(e.where().line, 2);
    EXPECT_EQ(fs::path(e.where().file).filename(), "b.mgf");
    EXPECT_NE(e.reason().find("include cycle: a.mgf -> b.mgf -> a.mgf"), std::string::npos) << e.what();
  }
  // Self include.
  dir.Write("self.mgf", "i self.mgf\n");
  EXPECT_THROW(LoadMgf(dir.path() / "self.mgf"), InputError);

  // A chain of 70 distinct files exceeds the include depth limit of 64.
  for (int i = 0; i < 70; ++i) {
    dir.Write("chain" + std::to_string(i) + ".mgf", "i chain" + std::to_string(i + 1) + ".mgf\n");
  }
  dir.Write("chain70.mgf", "# end\n");
  EXPECT_THAT(MgfErrorReason(dir.path() / "chain0.mgf"),
              ::testing::HasSubstr("includes nested deeper than 64"));

  // An include that leaves the include root is refused; inside it is fine.
  dir.Write("inner/scene.mgf", "i ../a.mgf\n");
  dir.Write("inner/ok.mgf", "i sub2/leaf.mgf\n");
  dir.Write("inner/sub2/leaf.mgf", "# nothing\n");
  MgfOptions o;
  o.include_root = dir.path() / "inner";
  EXPECT_THAT(MgfErrorReason(dir.path() / "inner/scene.mgf", o),
              ::testing::HasSubstr("resolves outside the scene folder"));
  EXPECT_NO_THROW(LoadMgf(dir.path() / "inner/ok.mgf", o));

  // Missing top-level file and a directory as include.
  EXPECT_THROW(LoadMgf(dir.path() / "nope.mgf"), InputError);
  dir.Write("dirinc.mgf", "i sub\n");
  EXPECT_THAT(MgfErrorReason(dir.path() / "dirinc.mgf"), ::testing::HasSubstr("not a regular file"));
  // An included file must balance its own xf.
  dir.Write("unbalanced.mgf", "xf -t 1 0 0\n");
  dir.Write("top.mgf", "xf -t 0 1 0\ni unbalanced.mgf\nxf\n");
  {
    const InputError e = MgfError(dir.path() / "top.mgf");
    EXPECT_EQ(fs::path(e.where().file).filename(), "unbalanced.mgf");
    EXPECT_EQ(e.where().line, 1);
  }
  dir.Write("closes.mgf", "xf\n");
  dir.Write("top2.mgf", "xf -t 0 1 0\ni closes.mgf\n");
  EXPECT_THROW(LoadMgf(dir.path() / "top2.mgf"), InputError);
}

TEST(MgfWarnings, UnknownEntitiesDegenerateFacesAndMetals) {
  const SceneDescription s = Load(std::string(kUnitSquare) +
                                  "frobnicate 1 2\n"  // line 10
                                  "frobnicate 3\n"    // same kind: no second warning
                                  "ies lamp.ies -t 0 0 1\n"
                                  "f a b b a\n"             // line 13: no area
                                  "f a b a\n"               // line 14: two distinct vertices
                                  "m metal =\n ir 0.5 3\n"  // line 16
                                  "f a b c d\n"
                                  "o open\n");  // line 18, never closed
  ASSERT_EQ(s.warnings.size(), 6u);
  EXPECT_EQ(s.warnings[0], "test.mgf:10: unknown entity 'frobnicate' ignored");
  EXPECT_EQ(s.warnings[1].rfind("test.mgf:12: ies", 0), 0u) << s.warnings[1];
  EXPECT_EQ(s.warnings[2].rfind("test.mgf:13: f: degenerate face", 0), 0u) << s.warnings[2];
  EXPECT_EQ(s.warnings[3].rfind("test.mgf:14: f: degenerate face", 0), 0u) << s.warnings[3];
  EXPECT_EQ(s.warnings[4].rfind("test.mgf:16: ir: imaginary part", 0), 0u) << s.warnings[4];
  EXPECT_EQ(s.warnings[5].rfind("test.mgf:18: 1 object context(s) not ended", 0), 0u) << s.warnings[5];
  EXPECT_EQ(s.NumTriangles(), 2u);
  EXPECT_FLOAT_EQ(s.materials[s.triangle_material[0]].ior, 0.5f);

  // Colours without luminance (the hospital scene has "cxy .4 0") fall back to grey.
  const SceneDescription grey = Load(std::string(kUnitSquare) + "m p =\n c\n  cxy .4 0\n rd .5\nf a b c d\n");
  ASSERT_EQ(grey.warnings.size(), 1u);
  EXPECT_EQ(grey.warnings[0].rfind("test.mgf:12: cxy: y = 0 is a colour without luminance", 0), 0u)
      << grey.warnings[0];
  EXPECT_NEAR(grey.materials[0].diffuse_reflectance.r, 0.5f, 1e-5f);
  EXPECT_NEAR(grey.materials[0].diffuse_reflectance.b, 0.5f, 1e-5f);

  // A self-intersecting face (edge e-a crosses edge c-d at x = 8/3; found by a search over
  // small integer polygons for one where no ear exists) still gives triangles and a warning.
  const SceneDescription bow = Load(R"(
v a =
  p 0 4 0
v b =
  p 4 3 0
v c =
  p 3 3 0
v d =
  p 1 1 0
v e =
  p 4 2 0
f a b c d e
)");
  EXPECT_GT(bow.NumTriangles(), 0u);
  ASSERT_FALSE(bow.warnings.empty());
  EXPECT_NE(bow.warnings[0].find("f: self-intersecting polygon"), std::string::npos) << bow.warnings[0];
}

// ---- 3. geometry -------------------------------------------------------------------------------

TEST(MgfGeometry, UnitSquareIsTwoTrianglesFacingZ) {
  const SceneDescription s = Load(std::string(kUnitSquare) + "f a b c d\n");
  ASSERT_EQ(s.NumTriangles(), 2u);
  EXPECT_NEAR(TotalArea(s), 1.0, 1e-12);
  for (size_t t = 0; t < 2; ++t) {
    const Vec3d n = Normalize(AreaVector(s, t));
    ExpectNear(n, {0, 0, 1}, 1e-12);  // counter-clockwise seen from +z: right-hand rule
  }
  EXPECT_TRUE(s.normals.empty());  // no vertex normals anywhere
  EXPECT_EQ(s.num_lights, 0u);
  EXPECT_EQ(s.triangle_light[0], kNoLight);
  // Reversed order faces -z.
  const SceneDescription r = Load(std::string(kUnitSquare) + "f d c b a\n");
  ExpectNear(Normalize(AreaVector(r, 0)), {0, 0, -1}, 1e-12);
}

TEST(MgfGeometry, ConcaveLShapeAreaIsExact) {
  // An L of area 3 (2x2 square minus a unit corner), given from a reflex vertex.
  const SceneDescription s = Load(R"(
v p0 =
  p 1 1 0
v p1 =
  p 1 2 0
v p2 =
  p 0 2 0
v p3 =
  p 0 0 0
v p4 =
  p 2 0 0
v p5 =
  p 2 1 0
f p0 p1 p2 p3 p4 p5
)");
  ASSERT_EQ(s.NumTriangles(), 4u);
  EXPECT_NEAR(TotalArea(s), 3.0, 1e-12);
  // No triangle may lie in the notch (1,1)-(2,2) and all face +z.
  for (size_t t = 0; t < s.triangles.size(); ++t) {
    EXPECT_GT(AreaVector(s, t).z, 0.0);
    Vec3d c;
    for (uint32_t v : s.triangles[t]) c += P(s, v) / 3.0;
    EXPECT_FALSE(c.x > 1.0 && c.y > 1.0) << "triangle in the notch";
  }
}

TEST(MgfGeometry, SeamHoleAndFhHoleGiveTheSameArea) {
  // The spec's wall with a window (§3 f, Figure 2): 4x3 wall, 1x1 window at (1..2, 1..2);
  // the outline runs counter-clockwise, the window clockwise, joined by the seam v4-v5.
  const std::string verts = R"(
v v1 =
  p 0 0 0
v v2 =
  p 4 0 0
v v3 =
  p 4 3 0
v v4 =
  p 0 3 0
v v5 =
  p 1 2 0
v v6 =
  p 2 2 0
v v7 =
  p 2 1 0
v v8 =
  p 1 1 0
)";
  const SceneDescription seam = Load(verts + "f v1 v2 v3 v4 v5 v6 v7 v8 v5 v4\n");
  EXPECT_NEAR(TotalArea(seam), 11.0, 1e-9);
  const SceneDescription holes = Load(verts + "fh v1 v2 v3 v4 - v5 v6 v7 v8\n");
  EXPECT_NEAR(TotalArea(holes), 11.0, 1e-9);
  // A hole given counter-clockwise is fixed up, not doubled.
  const SceneDescription ccw = Load(verts + "fh v1 v2 v3 v4 - v8 v7 v6 v5\n");
  EXPECT_NEAR(TotalArea(ccw), 11.0, 1e-9);
  for (const SceneDescription* s : {&seam, &holes, &ccw}) {
    for (size_t t = 0; t < s->triangles.size(); ++t) {
      EXPECT_GT(AreaVector(*s, t).z, 0.0);
      Vec3d c;
      for (uint32_t v : s->triangles[t]) c += P(*s, v) / 3.0;
      EXPECT_FALSE(c.x > 1 && c.x < 2 && c.y > 1 && c.y < 2) << "triangle inside the window";
    }
  }
  // Two holes.
  const SceneDescription two = Load(verts + R"(
v w1 =
  p 3 1 0
v w2 =
  p 3.5 1 0
v w3 =
  p 3.5 2 0
fh v1 v2 v3 v4 - v5 v6 v7 v8 - w1 w3 w2
)");
  EXPECT_NEAR(TotalArea(two), 11.0 - 0.25, 1e-9);
}

TEST(MgfGeometry, FaceVertexNormalsAreUsedOnlyWhenAllAreGiven) {
  const std::string base = std::string(kUnitSquare) + "v a\n n 0 0 2\nv b\n n 0 0 1\nv c\n n 0 1 1\n";
  const SceneDescription partial = Load(base + "f a b c d\n");
  EXPECT_TRUE(partial.normals.empty());
  const SceneDescription all = Load(base + "v d\n n 0 0 1\nf a b c d\n");
  ASSERT_EQ(all.normals.size(), all.positions.size());
  for (size_t i = 0; i < all.positions.size(); ++i) {
    EXPECT_NEAR(Length(Vec3d(all.normals[i])), 1.0, 1e-6);
    if (all.positions[i] == Vec3(1, 1, 0)) {
      ExpectNear(Vec3d(all.normals[i]), Vec3d(0, 1, 1) / std::sqrt(2.0), 1e-6);
    }
  }
}

TEST(MgfGeometry, SphereAreaVolumeAndOrientation) {
  // Rule (mgf_loader.h): N segments around, N/2 bands; vertices on the sphere. The inscribed
  // polyhedron's area is below 4πr² by about (π/N)²·2/3 relative; the bounds below are that
  // estimate with margin: 1.5 % for N = 24, 0.1 % for N = 96.
  for (const auto& [n, tol] :
       {std::pair{24, 0.015}, std::pair{12, 0.06}, std::pair{96, 0.001}, std::pair{3, 0.6}}) {
    MgfOptions o;
    o.curve_segments = n;
    const double r = 2.0;
    const SceneDescription s = Load("v c =\n p 1 2 3\nsph c 2\n", o);
    const double area = TotalArea(s);
    SCOPED_TRACE(n);
    EXPECT_LT(area, 4 * kPi * r * r);
    EXPECT_NEAR(area / (4 * kPi * r * r), 1.0, tol);
    std::printf("sphere N=%d: area / 4πr² = %.5f\n", n, area / (4 * kPi * r * r));
    // Closed and outward: every geometric normal points away from the centre, and the
    // smooth normals are the radial directions.
    ExpectNear(AreaVectorSum(s), {0, 0, 0}, 1e-9);
    for (size_t t = 0; t < s.triangles.size(); ++t) {
      Vec3d c;
      for (uint32_t v : s.triangles[t]) c += P(s, v) / 3.0;
      EXPECT_GT(Dot(AreaVector(s, t), c - Vec3d(1, 2, 3)), 0.0);
    }
    ASSERT_EQ(s.normals.size(), s.positions.size());
    for (size_t i = 0; i < s.positions.size(); ++i) {
      ExpectNear(Vec3d(s.normals[i]), (P(s, static_cast<uint32_t>(i)) - Vec3d(1, 2, 3)) / r, 1e-5);
    }
  }
  // Negative radius: same surface, inward.
  const SceneDescription in = Load("v c =\n p 0 0 0\nsph c -1\n");
  EXPECT_LT(SignedVolume(in), 0.0);
  const SceneDescription out = Load("v c =\n p 0 0 0\nsph c 1\n");
  EXPECT_GT(SignedVolume(out), 0.0);
  EXPECT_NEAR(SignedVolume(out), -SignedVolume(in), 1e-12);
  EXPECT_NEAR(SignedVolume(out) / (4.0 / 3.0 * kPi), 1.0, 0.03);
  for (size_t i = 0; i < in.normals.size(); ++i) {
    EXPECT_LT(Dot(Vec3d(in.normals[i]), P(in, static_cast<uint32_t>(i))), 0.0);
  }
}

TEST(MgfGeometry, CylinderConeRingTorusAreasAndOrientation) {
  MgfOptions o;
  o.curve_segments = 256;  // close to the smooth surfaces: 0.03 % chord error
  const double tol = 1e-3;
  const std::string axis = "v a =\n p 0 0 0\n n 0 0 1\nv b =\n p 0 0 2\n n 0 0 1\n";
  // Cylinder r=0.5, h=2: lateral area 2πrh, facing away from the axis.
  const SceneDescription cyl = Load(axis + "cyl a .5 b\n", o);
  EXPECT_NEAR(TotalArea(cyl) / (2 * kPi * 0.5 * 2), 1.0, tol);
  for (size_t t = 0; t < cyl.triangles.size(); ++t) {
    Vec3d c;
    for (uint32_t v : cyl.triangles[t]) c += P(cyl, v) / 3.0;
    EXPECT_GT(Dot(AreaVector(cyl, t), Vec3d(c.x, c.y, 0)), 0.0);
  }
  const SceneDescription cyl_in = Load(axis + "cyl a -.5 b\n", o);
  for (size_t t = 0; t < cyl_in.triangles.size(); ++t) {
    Vec3d c;
    for (uint32_t v : cyl_in.triangles[t]) c += P(cyl_in, v) / 3.0;
    EXPECT_LT(Dot(AreaVector(cyl_in, t), Vec3d(c.x, c.y, 0)), 0.0);
  }
  // Cone to a point: lateral area π r s with slant s; smooth normals tilt upwards.
  const SceneDescription cone = Load(axis + "cone a 1 b 0\n", o);
  EXPECT_NEAR(TotalArea(cone) / (kPi * 1.0 * std::sqrt(1.0 + 4.0)), 1.0, tol);
  for (const Vec3& n : cone.normals) {
    EXPECT_NEAR(n.z, 1.0 / std::sqrt(5.0), 1e-5);  // cone normal: (2ρ + 1·z)/√5
  }
  // Frustum r 1 -> 0.5.
  const SceneDescription frustum = Load(axis + "cone a 1 b .5\n", o);
  EXPECT_NEAR(TotalArea(frustum) / (kPi * 1.5 * std::sqrt(0.25 + 4.0)), 1.0, tol);
  // Closed capped cylinder (the spec's "v" example): outward everywhere, volume πr²h.
  const SceneDescription capped = Load(
      "v e1 =\n p 0 0 0\n n 0 0 -1\nv e2 =\n p 0 0 1\n n 0 0 1\n"
      "cyl e1 1.2 e2\nring e1 0 1.2\nring e2 0 1.2\n",
      o);
  EXPECT_NEAR(SignedVolume(capped) / (kPi * 1.44), 1.0, tol);
  ExpectNear(AreaVectorSum(capped), {0, 0, 0}, 1e-9);
  // Ring with a hole faces its centre's normal.
  const SceneDescription ring = Load("v c =\n p 0 0 0\n n 0 1 0\nring c 1 2\n", o);
  EXPECT_NEAR(TotalArea(ring) / (kPi * 3.0), 1.0, tol);
  for (size_t t = 0; t < ring.triangles.size(); ++t) EXPECT_GT(AreaVector(ring, t).y, 0.0);
  // Torus (inner 1, outer 3): tube radius 1 around a circle of radius 2; area 4π²Rr.
  const SceneDescription torus = Load("v c =\n p 0 0 0\n n 0 0 1\ntorus c 1 3\n", o);
  EXPECT_NEAR(TotalArea(torus) / (4 * kPi * kPi * 2 * 1), 1.0, tol);
  EXPECT_NEAR(SignedVolume(torus) / (2 * kPi * kPi * 2 * 1), 1.0, tol);  // outward
  const SceneDescription torus_in = Load("v c =\n p 0 0 0\n n 0 0 1\ntorus c -1 -3\n", o);
  EXPECT_NEAR(SignedVolume(torus_in), -SignedVolume(torus), 1e-9);
}

TEST(MgfGeometry, PrismIsClosedAndOutward) {
  // The spec's unit cube example: the face looks down -z, extruded by 1 to +z.
  const std::string cube = kCubeBase;
  const SceneDescription s = Load(cube + "prism cv0 cv1 cv2 cv3 1\n");
  EXPECT_EQ(s.NumTriangles(), 12u);
  EXPECT_NEAR(TotalArea(s), 6.0, 1e-12);
  EXPECT_NEAR(SignedVolume(s), 1.0, 1e-12);  // outward
  Bounds3 b = s.ComputeBounds();
  ExpectNear(Vec3d(b.lo), {0, 0, 0}, 0);
  ExpectNear(Vec3d(b.hi), {1, 1, 1}, 0);
  const SceneDescription in = Load(cube + "prism cv0 cv1 cv2 cv3 -1\n");
  EXPECT_NEAR(SignedVolume(in), -1.0, 1e-12);  // above the face, inward
  EXPECT_NEAR(in.ComputeBounds().lo.z, -1.0f, 0);
  EXPECT_EQ(s.num_lights, 0u);
  // One prism is one light source.
  const SceneDescription lit = Load("m e =\n ed 100\n" + cube + "prism cv0 cv1 cv2 cv3 1\n");
  EXPECT_EQ(lit.num_lights, 1u);
  EXPECT_EQ(lit.NumEmissiveTriangles(), 12u);
}

TEST(MgfTransforms, TranslateScaleRotateMirror) {
  const std::string pt = "v c =\n p 1 0 0\n";
  auto centre = [&](const std::string& xf) { return Centroid(Load(pt + "xf " + xf + "\nsph c .01\nxf\n")); };
  ExpectNear(centre("-t 1 2 3"), {2, 2, 3}, 1e-6);
  ExpectNear(centre("-s 2"), {2, 0, 0}, 1e-6);
  ExpectNear(centre("-rz 90"), {0, 1, 0}, 1e-6);   // counter-clockwise about +z
  ExpectNear(centre("-ry 90"), {0, 0, -1}, 1e-6);  // x -> -z about +y
  ExpectNear(centre("-rx 90"), {1, 0, 0}, 1e-6);
  ExpectNear(centre("-rz 30"), {std::cos(kPi / 6), std::sin(kPi / 6), 0}, 1e-6);
  ExpectNear(centre("-mx"), {-1, 0, 0}, 1e-6);
  // Arguments act left to right on the object: scale, then move; vs move, then scale.
  ExpectNear(centre("-s 2 -t 1 0 0"), {3, 0, 0}, 1e-6);
  ExpectNear(centre("-t 1 0 0 -s 2"), {4, 0, 0}, 1e-6);
  // Nested xf: the enclosed transform is applied first (§2.2.2 example: ring at (5,-10,0)).
  const SceneDescription ring =
      Load("xf -t 5 0 0\nv v1 =\n p 0 10 0\n n 0 0 1\nxf -rx 180\nring v1 0 2\nxf\nxf\n");
  ExpectNear(Centroid(ring), {5, -10, 0}, 1e-6);
  for (size_t t = 0; t < ring.triangles.size(); ++t) EXPECT_LT(AreaVector(ring, t).z, 0.0);
  // -i N repeats: four quarter turns are the identity.
  ExpectNear(centre("-i 4 -rz 90"), {1, 0, 0}, 1e-6);
  ExpectNear(centre("-i 3 -t 1 0 0"), {4, 0, 0}, 1e-6);
  // Scaling scales radii too.
  const SceneDescription big = Load(pt + "xf -s 3\nsph c 1\nxf\n");
  EXPECT_NEAR(big.ComputeBounds().Diagonal().x, 6.0f, 1e-4f);
}

TEST(MgfTransforms, MirrorKeepsFacesOutward) {
  // A mirrored closed object stays outward (odd mirrors reverse the face order).
  const std::string cube = kCubeBase;
  for (const char* xf : {"-mx", "-my", "-mz", "-mx -my", "-s -1", "-mz -rx 33 -t 1 2 3"}) {
    const SceneDescription s = Load(cube + "xf " + xf + "\nprism cv0 cv1 cv2 cv3 1\nxf\n");
    EXPECT_NEAR(SignedVolume(s), 1.0, 1e-6) << xf;
  }
  // A single face: mirroring flips where it faces, like a mirrored vector.
  const SceneDescription f = Load(std::string(kUnitSquare) + "xf -mz\nf a b c d\nxf\n");
  ExpectNear(Normalize(AreaVector(f, 0)), {0, 0, -1}, 1e-12);
  const SceneDescription g = Load(std::string(kUnitSquare) + "xf -mx\nf a b c d\nxf\n");
  ExpectNear(Normalize(AreaVector(g, 0)), {0, 0, 1}, 1e-12);
}

TEST(MgfTransforms, ArraysRepeatTheBlock) {
  // §2.2.3 example: 60 spheres in a 3x4x5 array moved to (15,30,45).
  MgfOptions o;
  o.curve_segments = 4;
  const std::string text =
      "m lit =\n ed 1\nv v0 =\n p 0 0 0\n"
      "xf -a 3 -t 1 0 0 -a 4 -t 0 1 0 -a 5 -t 0 0 1 -i 1 -t 15 30 45\nsph v0 0.1\nxf\n";
  const SceneDescription s = Load(text, o);
  EXPECT_EQ(s.num_lights, 60u);  // every instance is its own light
  const size_t per_sphere = s.NumTriangles() / 60;
  EXPECT_EQ(s.NumTriangles(), per_sphere * 60);
  const auto [lo, hi] = WorldBoundsOf(s);
  ExpectNear(lo, {14.9, 29.9, 44.9}, 1e-4);
  ExpectNear(hi, {17.1, 33.1, 49.1}, 1e-4);
  // A block with redefinitions inside is re-executed: the vertex moves each time.
  const SceneDescription moving =
      Load("v p =\n p 0 0 0\nxf -a 3 -t 10 0 0\nsph p .1\nv p\n p 0 1 0\nxf\n", o);
  const Bounds3 mb = moving.ComputeBounds();
  EXPECT_NEAR(mb.lo.y, -0.1f, 1e-5f);  // first instance at y = 0
  EXPECT_NEAR(mb.hi.y, 1.1f, 1e-5f);   // later ones at y = 1
  EXPECT_NEAR(mb.hi.x, 20.1f, 1e-5f);
  // Circle of 6 spheres (§3 p example): -a 6 -rz 60.
  const SceneDescription circle = Load("v s =\n p 1 0 0\nxf -a 6 -rz 60\nsph s .05\nxf\n", o);
  EXPECT_EQ(circle.NumTriangles(), 6 * (circle.NumTriangles() / 6));
  EXPECT_NEAR(Centroid(circle).x, 0.0, 1e-6);
  EXPECT_NEAR(Centroid(circle).y, 0.0, 1e-6);
  // Nested arrays multiply.
  const SceneDescription nested =
      Load(std::string(kUnitSquare) + "xf -a 2 -t 0 0 1\nxf -a 3 -t 2 0 0\nf a b c d\nxf\nxf\n");
  EXPECT_EQ(nested.NumTriangles(), 12u);
  EXPECT_NEAR(TotalArea(nested), 6.0, 1e-9);
}

TEST(MgfIncludes, RelativeIncludesWithTransformsAndArrays) {
  TempDir dir;
  dir.Write("lib/square.mgf",
            "v a =\n p 0 0 0\nv b =\n p 1 0 0\nv c =\n p 1 1 0\nv d =\n p 0 1 0\nf a b c d\n"
            "i ../common/mat.mgf\n");  // relative to lib/, not to the including file
  dir.Write("common/mat.mgf", "m red =\n c\n  cxy .64 .33\n rd .2\n");
  dir.Write("scene.mgf",
            "i lib/square.mgf -t 10 0 0\n"
            "i lib/square.mgf -s 2 -a 3 -t 0 5 0\n"
            "m red\n"  // defined by the include
            "i ./lib/../lib/square.mgf\n");
  const SceneDescription s = LoadMgf(dir.path() / "scene.mgf");
  EXPECT_EQ(s.NumTriangles(), 2u * (1 + 3 + 1));
  EXPECT_NEAR(TotalArea(s), 1 + 3 * 4 + 1, 1e-9);
  const Bounds3 b = s.ComputeBounds();
  EXPECT_FLOAT_EQ(b.hi.x, 11.0f);
  EXPECT_FLOAT_EQ(b.hi.y, 12.0f);  // third instance: y in [10, 12]
  // Through LoadMgfFromString, includes are relative to the virtual name's directory.
  const SceneDescription v =
      LoadMgfFromString("i lib/square.mgf -t 0 0 1\n", (dir.path() / "virtual.mgf").string());
  EXPECT_EQ(v.NumTriangles(), 2u);
  EXPECT_FLOAT_EQ(v.ComputeBounds().lo.z, 1.0f);
  // Errors inside an included file name that file and line.
  dir.Write("lib/broken.mgf", "# ok\n\nsph nowhere 1\n");
  dir.Write("scene_broken.mgf", "i lib/broken.mgf\n");
  {
    const InputError e = MgfError(dir.path() / "scene_broken.mgf");
    EXPECT_EQ(fs::path(e.where().file).filename(), "broken.mgf");
    EXPECT_EQ(e.where().line, 3);
    EXPECT_NE(e.reason().find("undefined vertex 'nowhere'"), std::string::npos);
  }
}

TEST(MgfSyntax, ContinuationCommentsAndLineEnds) {
  // Backslash continuation joins lines; CR and CRLF end lines; "#word" is a comment.
  const SceneDescription s = LoadMgfFromString(
      "#comment without blank\r\nv a =\r\n p 0 \\\r\n 0 0\rv b =\n p 1 0 0\nv c =\n p 1 1 0\n"
      "# a comment \\\n f a b c\n"  // continued comment: not a face
      "f a \\\n b \\\n c\n",
      "cont.mgf");
  EXPECT_EQ(s.NumTriangles(), 1u);
  EXPECT_TRUE(s.warnings.empty());
  // Line numbers keep counting across CR, CRLF and continuations.
  try {
    LoadMgfFromString("a\r\nb\rx \\\nd\n\nsph\n", "lines.mgf");
    ADD_FAILURE();
  } catch (const InputError& e) {
    EXPECT_EQ(e.where().ToString(), "lines.mgf:6");
  }
  // Tabs, leading blanks and a '+' sign are fine.
  const SceneDescription t =
      Load("\tv a =\n\t\tp\t+1 .5 -2.\n v b =\n p 0 0 0\n v c =\n p 0 1 0\n f a b c\n");
  EXPECT_FLOAT_EQ(t.positions[0].x, 1.0f);
}

TEST(MgfContexts, NamedContextsAreCapturedByValue) {
  const SceneDescription s = Load(std::string(kUnitSquare) +
                                  "m paint =\n rd .5\n"
                                  "f a b c d\n"         // grey 0.5
                                  "m paint\n rd .25\n"  // later change: earlier face unchanged
                                  "f a b c d\n"
                                  "m copy = paint\n"   // copy of the current values
                                  "m paint\n rd .1\n"  // does not affect the copy
                                  "m copy\nf a b c d\n"
                                  "v a\n p -1 0 0\n"  // moving a vertex after use
                                  "m\nf a b c d\n");  // unnamed: back to black absorber
  ASSERT_EQ(s.NumTriangles(), 8u);
  auto rd = [&](size_t t) { return s.materials[s.triangle_material[t]].diffuse_reflectance; };
  EXPECT_NEAR(rd(0).g, 0.5f, 1e-5f);
  EXPECT_NEAR(rd(2).g, 0.25f, 1e-5f);
  EXPECT_NEAR(rd(4).g, 0.25f, 1e-5f);
  EXPECT_EQ(s.materials[s.triangle_material[4]].name, "copy");
  EXPECT_TRUE(rd(6).IsBlack());
  for (size_t t = 0; t < 6; ++t) {  // the faces made before "a" moved keep its old position
    for (uint32_t v : s.triangles[t]) EXPECT_GE(s.positions[v].x, 0.0f);
  }
  EXPECT_FLOAT_EQ(s.ComputeBounds().lo.x, -1.0f);
  // The colour is captured when rd is given, not when the face is made.
  const SceneDescription c = Load(std::string(kUnitSquare) +
                                  "c red =\n cxy .64 .33\nm m1 =\n c red\n rd .2\n"
                                  "c red\n cxy .15 .06\n"  // redefine red afterwards
                                  "m m1\nf a b c d\n");
  const Rgb r = c.materials[c.triangle_material[0]].diffuse_reflectance;
  EXPECT_GT(r.r, r.b);
  // Identical materials are shared.
  const SceneDescription d =
      Load(std::string(kUnitSquare) + "m x =\n rd .3\nf a b c d\nm y = x\nm x\nf a b c d\n");
  EXPECT_EQ(d.materials.size(), 1u);
}

// ---- colour and emission -----------------------------------------------------------------------

TEST(MgfColour, SpecWhitePointIsNeutralAndLuminanceWeightsMatchTheSpec) {
  const Rgb w = mgf::CieToRgb(1.0 / 3.0, 1.0 / 3.0, 1.0);
  EXPECT_NEAR(w.r, 1.0f, 1e-5f);
  EXPECT_NEAR(w.g, 1.0f, 1e-5f);
  EXPECT_NEAR(w.b, 1.0f, 1e-5f);
  // §6.1.1: "cmix 0.265 R 0.670 G 0.065 B" of the primaries "would result a pure white".
  const SceneDescription s = Load(std::string(kUnitSquare) +
                                  "c R =\n cxy 0.640 0.330\nc G =\n cxy 0.290 0.600\n"
                                  "c B =\n cxy 0.150 0.060\nc white =\n cmix 0.265 R 0.670 G 0.065 B\n"
                                  "m w =\n rd .8\nf a b c d\n");
  const Rgb rd = s.materials[0].diffuse_reflectance;
  EXPECT_NEAR(rd.r, 0.8f, 0.004f);
  EXPECT_NEAR(rd.g, 0.8f, 0.004f);
  EXPECT_NEAR(rd.b, 0.8f, 0.004f);
  // Each primary converts to a pure channel.
  const Rgb red = mgf::CieToRgb(0.64, 0.33, 1.0);
  EXPECT_GT(red.r, 1.0f);
  EXPECT_NEAR(red.g, 0.0f, 1e-5f);
  EXPECT_NEAR(red.b, 0.0f, 1e-5f);
}

TEST(MgfColour, FlatSpectrumIsNeutralAndBlackBodiesAreOnThePlanckianLocus) {
  const std::vector<double> flat(31, 42.0);
  double x, y;
  ASSERT_TRUE(mgf::SpectrumToXy(380, 780, flat.data(), flat.size(), &x, &y));
  EXPECT_NEAR(x, 1.0 / 3.0, 5e-4);
  EXPECT_NEAR(y, 1.0 / 3.0, 5e-4);
  const Rgb rgb = mgf::CieToRgb(x, y, 1.0);
  EXPECT_NEAR(rgb.r, rgb.g, 0.005f);
  EXPECT_NEAR(rgb.b, rgb.g, 0.005f);
  // The same through the file: "cspec" with a flat spectrum gives a grey material.
  const SceneDescription s =
      Load(std::string(kUnitSquare) + "m g =\n c\n  cspec 400 700 1 1 1 1\n rd .5\nf a b c d\n");
  const Rgb g = s.materials[0].diffuse_reflectance;
  EXPECT_NEAR(g.r, 0.5f, 0.01f);
  EXPECT_NEAR(g.g, 0.5f, 0.01f);
  EXPECT_NEAR(g.b, 0.5f, 0.01f);
  // A line at 520 nm lands on the spectral locus there, (0.0743, 0.8338).
  const double line[2] = {1, 1};
  ASSERT_TRUE(mgf::SpectrumToXy(519.5, 520.5, line, 2, &x, &y));
  EXPECT_NEAR(x, 0.0743, 0.0005);
  EXPECT_NEAR(y, 0.8338, 0.0005);
  // Black bodies: Planck's law sampled by hand at 5 nm for 2856 K (CIE illuminant A) lands on
  // A's chromaticity (0.4476, 0.4074), and "cct 2856" gives the same colour as that spectrum.
  std::vector<double> planck;
  std::string planck_words;
  for (int l = 380; l <= 780; l += 5) {
    const double lm = l * 1e-9;
    // Scaled so that six decimals keep four significant digits at the blue end.
    planck.push_back(1e4 / (std::pow(lm * 1e6, 5) * std::expm1(1.4387769e-2 / (lm * 2856.0))));
    planck_words += ' ';
    planck_words += std::to_string(planck.back());
  }
  ASSERT_TRUE(mgf::SpectrumToXy(380, 780, planck.data(), planck.size(), &x, &y));
  EXPECT_NEAR(x, 0.4476, 0.002);
  EXPECT_NEAR(y, 0.4074, 0.002);
  const SceneDescription a = Load(std::string(kUnitSquare) +
                                  "m l =\n c\n  cct 2856\n rd .5\nf a b c d\n"
                                  "m s =\n c\n  cspec 380 780" +
                                  planck_words + "\n rd .5\nf a b c d\n");
  ASSERT_EQ(a.materials.size(), 2u);
  const Rgb cct = a.materials[0].diffuse_reflectance;
  const Rgb spec = a.materials[1].diffuse_reflectance;
  EXPECT_GT(cct.r, cct.g);  // warm
  EXPECT_GT(cct.g, cct.b);
  EXPECT_NEAR(cct.r, spec.r, 0.002f);
  EXPECT_NEAR(cct.g, spec.g, 0.002f);
  EXPECT_NEAR(cct.b, spec.b, 0.002f);
}

TEST(MgfEmission, EdConvertsWithOneOverPiTimes179) {
  // Le = ed / (π · 179) × RGB(colour, Y = 1): ed = π·179 lm/m² of neutral colour is Le = 1.
  const double ed = kPi * mgf::kLuminousEfficacy;
  const SceneDescription s =
      Load(std::string(kUnitSquare) + "m lamp =\n ed " + std::to_string(ed) + "\nf a b c d\n");
  ASSERT_EQ(s.materials.size(), 1u);
  const Rgb e = s.materials[0].emission;
  EXPECT_NEAR(e.r, 1.0f, 1e-5f);
  EXPECT_NEAR(e.g, 1.0f, 1e-5f);
  EXPECT_NEAR(e.b, 1.0f, 1e-5f);
  EXPECT_EQ(s.num_lights, 1u);
  EXPECT_EQ(s.triangle_light[0], 0u);
  EXPECT_EQ(s.triangle_light[1], 0u);  // one face = one light, both triangles
  // Coloured emitters keep luminance 1 per unit: Y of the RGB (spec weights) is ed/(π·179).
  const SceneDescription c =
      Load(std::string(kUnitSquare) + "m lamp =\n c\n  cxy .373 .385\n ed 1000\nf a b c d\n");
  const Rgb ce = c.materials[0].emission;
  const double Y = 0.26510582 * ce.r + 0.67010582 * ce.g + 0.06478836 * ce.b;
  EXPECT_NEAR(Y, 1000.0 / ed, 1e-4);
  // Separate primitives are separate lights; non-emitters get kNoLight.
  const SceneDescription two = Load(std::string(kUnitSquare) +
                                    "m dark =\n rd .5\nf a b c d\n"
                                    "m lamp =\n ed 100\nf a b c d\nf d c b a\n"
                                    "v o =\n p 5 5 5\nsph o 1\n");
  EXPECT_EQ(two.num_lights, 3u);
  EXPECT_EQ(two.triangle_light[0], kNoLight);
  EXPECT_EQ(two.triangle_light[2], 0u);
  EXPECT_EQ(two.triangle_light[4], 1u);
  EXPECT_EQ(two.triangle_light.back(), 2u);
}

TEST(MgfMaterials, ValuesMapToTheMaterialAndAreEnergyConserving) {
  const SceneDescription s = Load(std::string(kUnitSquare) +
                                  "m glass =\n sides 1\n ir 1.52 0\n c\n rs .06 .02\n"
                                  " td .1\n ts .8 .05\nf a b c d\n");
  const Material& m = s.materials[0];
  EXPECT_NEAR(m.specular_reflectance.g, 0.06f, 1e-6f);
  EXPECT_FLOAT_EQ(m.specular_roughness, 0.02f);
  EXPECT_NEAR(m.diffuse_transmittance.g, 0.1f, 1e-6f);
  EXPECT_NEAR(m.specular_transmittance.g, 0.8f, 1e-6f);
  EXPECT_FLOAT_EQ(m.transmission_roughness, 0.05f);
  EXPECT_FLOAT_EQ(m.ior, 1.52f);
  EXPECT_TRUE(m.one_sided);
  EXPECT_EQ(m.name, "glass");
  // Too much in one channel: scaled to 1 and warned.
  const SceneDescription hot =
      Load(std::string(kUnitSquare) + "m red =\n c\n  cxy .64 .33\n rd .6\n c\n rs .3 0\nf a b c d\n");
  const Material& h = hot.materials[0];
  const Rgb sum = h.diffuse_reflectance + h.specular_reflectance;
  EXPECT_NEAR(sum.Max(), 1.0f, 1e-5f);
  ASSERT_EQ(hot.warnings.size(), 1u);
  EXPECT_NE(hot.warnings[0].find("scaled down"), std::string::npos);
}

}  // namespace
}  // namespace pf
