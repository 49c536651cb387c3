// The EXR header of a render (common/plan/render_header.h): every setting of the table, the scene,
// the camera and the plan, written through OpenEXR and read back equal; real numbers in the
// shortest text that reads back bit-exactly (common/core/real_text.h).

#include <gtest/gtest.h>

#include <cmath>
#include <cstdlib>
#include <cstring>
#include <random>
#include <set>
#include <string>
#include <vector>

#include "common/core/real_text.h"
#include "common/image/exr_io.h"
#include "common/plan/render_header.h"
#include "common/render/integrator_factory.h"
#include "common/render/render_settings_table.h"
#include "common/render/render_settings_text.h"

namespace pf {
namespace {

// "x,y,z" split at the commas.
std::vector<std::string> Components(const std::string& text) {
  std::vector<std::string> out(1);
  for (char c : text) {
    if (c == ',')
      out.emplace_back();
    else
      out.back().push_back(c);
  }
  return out;
}

bool SameBits(float a, float b) {
  return std::memcmp(&a, &b, sizeof a) == 0;
}
bool SameBits(double a, double b) {
  return std::memcmp(&a, &b, sizeof a) == 0;
}

RenderRecord Record() {
  RenderRecord r;
  r.scene = "cornell.mgf";
  r.scene_hash = std::string(64, 'a');
  r.camera.eye = Vec3d(Vec3(3.9f, 0.1f, -2.5f));    // a float camera (an MGF scene's)
  r.camera.look_at = Vec3d(0.1, 1.0 + 1e-12, 7.0);  // doubles that are no float
  r.camera.up = Vec3(0.0f, 1.0f, 0.3f);
  r.camera.vfov_degrees = 39.6f;
  r.settings.direct = DirectLightMode::kPhotonDirect;  // resolved
  r.settings.caustic = CausticMapMode::kOn;
  r.settings.caustic_radius = 0.03f;
  r.settings.light_uniform_fraction = 0.1f;
  r.settings.importance_min_probability = 0.07f;
  r.settings.progressive_alpha = 0.7;  // a double setting
  r.plan.kind = PlanKind::kMultipleMaps;
  r.plan.maps = 4;
  r.plan.samples_per_pixel = 2;
  r.plan.tile_size = 64;
  r.plan.tail_tile_size = 32;
  r.seed = 17;
  return r;
}

ImageMetadata WrittenAndRead(const RenderRecord& record) {
  ImageMetadata meta;
  RecordRender(record, meta);
  Image image(2, 2);
  ImageMetadata read;
  DecodeExrFromMemory(EncodeExrToMemory(image, meta), &read);
  return read;
}

TEST(RenderHeader, EverySettingOfTheTableReadsBackEqual) {
  const RenderRecord record = Record();
  ImageMetadata meta = WrittenAndRead(record);
  JobRenderSettings read;  // defaults, then every header value
  for (const RenderSetting& row : RenderSettingsTable()) {
    const std::string key = SettingHeaderKey(row.name);
    SCOPED_TRACE(key);
    ASSERT_EQ(meta.count(key), 1u);  // the photon-map integrator reads every row
    SetRenderSetting(read, row.name, meta[key], key);
    const RenderSettingValue want = row.get(record.settings), got = row.get(read);
    ASSERT_EQ(want.index(), got.index());
    if (const double* d = std::get_if<double>(&want))
      EXPECT_TRUE(SameBits(*d, std::get<double>(got))) << meta[key];
    else
      EXPECT_EQ(want, got);
  }
  EXPECT_EQ(meta["settings.caustic-radius"], "0.03");
  EXPECT_EQ(meta["settings.progressive-alpha"], "0.7");
  EXPECT_EQ(meta["settings.direct"], "photon-direct");
}

TEST(RenderHeader, PathTracerRecordsTheRowsItReads) {
  RenderRecord record = Record();
  record.settings.integrator = IntegratorKind::kPath;
  const ImageMetadata meta = WrittenAndRead(record);
  for (const RenderSetting& row : RenderSettingsTable())
    EXPECT_EQ(meta.count(SettingHeaderKey(row.name)), IntegratorReads(record.settings, row) ? 1u : 0u)
        << row.name;
}

TEST(RenderHeader, CameraReadsBackBitExactly) {
  const RenderRecord record = Record();
  ImageMetadata meta = WrittenAndRead(record);
  EXPECT_EQ(meta["camera.eye"], "3.9,0.1,-2.5");  // not 3.9000000953674316
  const std::vector<std::string> eye = Components(meta["camera.eye"]);
  ASSERT_EQ(eye.size(), 3u);
  EXPECT_TRUE(SameBits(std::strtof(eye[0].c_str(), nullptr), 3.9f));
  EXPECT_TRUE(SameBits(std::strtof(eye[1].c_str(), nullptr), 0.1f));
  // Widened, the float read back is the double the camera held.
  EXPECT_TRUE(SameBits(double(std::strtof(eye[0].c_str(), nullptr)), record.camera.eye.x));
  const std::vector<std::string> look_at = Components(meta["camera.look_at"]);
  ASSERT_EQ(look_at.size(), 3u);
  EXPECT_TRUE(SameBits(std::strtod(look_at[0].c_str(), nullptr), 0.1));
  EXPECT_TRUE(SameBits(std::strtod(look_at[1].c_str(), nullptr), 1.0 + 1e-12));
  EXPECT_EQ(meta["camera.up"], "0,1,0.3");
  EXPECT_EQ(meta["camera.vfov_degrees"], "39.6");
  EXPECT_TRUE(SameBits(std::strtof(meta["camera.vfov_degrees"].c_str(), nullptr), 39.6f));
}

TEST(RenderHeader, SceneAndPlanAndSeed) {
  ImageMetadata meta = WrittenAndRead(Record());
  EXPECT_EQ(meta["scene"], "cornell.mgf");
  EXPECT_EQ(meta["scene.hash"], std::string(64, 'a'));
  EXPECT_EQ(meta["plan"], "multiple-maps maps=4 spp=2 tile=64");  // the tail tile changes no pixel
  EXPECT_EQ(meta["seed"], "17");
}

TEST(RenderHeader, PlanRecordTextNamesEveryParameterLikePfRender) {
  PlanSpec p;
  p.kind = PlanKind::kSkipping;
  p.stride = 4;
  p.rounds = 3;
  p.samples_per_pixel = 2;
  EXPECT_EQ(PlanRecordText(p), "skipping stride=4 rounds=3 spp=2");
  p.kind = PlanKind::kMapsInTurn;
  EXPECT_EQ(PlanRecordText(p), "maps-in-turn spp=2 tile=0");
  p.kind = PlanKind::kProgressive;
  p.maps = 8;
  EXPECT_EQ(PlanRecordText(p), "progressive passes=8 spp=2 tile=0");
  p = PlanSpec{};
  p.kind = PlanKind::kHierarchical;
  p.decay = 1.5;
  p.localize_contrast = 0.1f;  // a float's text, as pf render's flag gives it
  EXPECT_EQ(PlanRecordText(p),
            "hierarchical levels=4 dims=1 base-samples=8 min-samples=1 decay=1.5 localize-threshold=4 "
            "localize-contrast=0.1 tile=0 hier-part=all");
  p.hierarchy_part = HierarchyPart::kIndirect;
  p.direct_samples = 3;
  EXPECT_NE(PlanRecordText(p).find("hier-part=indirect hier-direct-samples=3"), std::string::npos);
  // Any other parameter gives another text.
  PlanSpec q = p;
  q.levels = 5;
  EXPECT_NE(PlanRecordText(q), PlanRecordText(p));
}

TEST(RenderHeader, SameRenderKeysAreSceneCameraAndSettings) {
  for (const char* key : {"scene", "scene.hash", "camera.eye", "camera.vfov_degrees", "settings.photons"})
    EXPECT_TRUE(SameRenderKey(key)) << key;
  for (const char* key : {"plan", "seed", "spp", "date", "version", "job_name", "render_seconds"})
    EXPECT_FALSE(SameRenderKey(key)) << key;
}

TEST(RealText, ShortestTextReadsBackBitExactly) {
  EXPECT_EQ(RealText(double(3.9f)), "3.9");
  EXPECT_EQ(RealText(0.05), "0.05");
  EXPECT_EQ(RealText(2.0 / 3.0), "0.6666666666666666");
  EXPECT_EQ(RealText(Vec3d(1, -0.5, 1e30)), "1,-0.5,1e+30");
  std::mt19937_64 rng(7);
  std::uniform_real_distribution<double> u(-1e3, 1e3);
  for (int i = 0; i < 20000; ++i) {
    const double d = u(rng);
    const float f = float(d);
    const std::string df = RealText(double(f)), dd = RealText(d);
    ASSERT_TRUE(SameBits(std::strtof(df.c_str(), nullptr), f)) << df;
    ASSERT_TRUE(SameBits(std::strtod(dd.c_str(), nullptr), d)) << dd;
    // One float step apart: another text.
    ASSERT_NE(RealText(double(std::nextafter(f, 2e3f))), df);
  }
}

}  // namespace
}  // namespace pf
