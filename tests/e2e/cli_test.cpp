// The command-line contract of pf, pf-worker and pf-coordinator as a new user meets it (docs/farm.md,
// "Command-line contract"; "rough edges"): usage errors exit 2 in all three, --version, names that say what
// is written, outputs checked before the work, the farm's limits, manifest settings and warnings, pf merge's
// weights, pf info on an EXR. Every test runs the real binaries.
#include <gtest/gtest.h>

#include <fstream>

#include "common/image/exr_io.h"
#include "tests/e2e/harness.h"

namespace pf::e2e {
namespace {

namespace fs = std::filesystem;

// A tiny path-traced render: fast enough to run many times.
std::vector<std::string> TinyRender(const std::string& scene, const fs::path& out) {
  return {Binaries::Pf(), "render",   scene, "--res",     "8x8", "--spp", "1",
          "-q",           "--no-png", "-o",  out.string()};
}

ImageMetadata HeaderOf(const fs::path& exr) {
  ImageMetadata meta;
  ReadExr(exr.string(), &meta);
  return meta;
}

// A Cornell box manifest in `dir` (next to copies of its geometry) with extra JSON.
fs::path WriteManifest(const fs::path& dir, const std::string& extra) {
  for (const char* file : {"CornellBox-Original.obj", "CornellBox-Original.mtl"})
    fs::copy_file(fs::path(Binaries::Scene()).parent_path() / file, dir / file,
                  fs::copy_options::overwrite_existing);
  const fs::path path = dir / "box.json";
  std::ofstream(path) << "{\"version\": 1, \"name\": \"box\", \"geometry\": \"CornellBox-Original.obj\",\n"
                      << " \"cameras\": [{\"name\": \"main\", \"eye\": [0, 1, 3.9], \"look_at\": [0, 1, 0],"
                      << " \"up\": [0, 1, 0], \"fov\": 39.3, \"resolution\": [16, 16]}]" << extra << "}\n";
  return path;
}

TEST(Cli, UsageErrorsExitTwoInAllThreeBinaries) {
  TestDir dir;
  for (const std::string& bin : {Binaries::Pf(), Binaries::Worker(), Binaries::Coordinator()}) {
    const RunResult r = RunCommand({bin, "--no-such-flag"}, dir.path(), 30);
    EXPECT_EQ(r.exit_code, 2) << bin << ": " << r.err;
  }
  // A flag value out of range, the other CLI11 error (pf-coordinator used to exit 105).
  const RunResult r = RunCommand({Binaries::Coordinator(), "--max-attempts", "0"}, dir.path(), 30);
  EXPECT_EQ(r.exit_code, 2) << r.err;
}

// pf-coordinator --config FILE: options by long name in TOML, the command line over the file, an
// unknown key or an unreadable file a usage error naming it (deploy/README.md).
TEST(Cli, CoordinatorConfigFileSetsOptionsAndTheCommandLineWins) {
  TestDir dir;
  {
    std::ofstream(dir / "coordinator.toml") << "# a deployment's settings\n"
                                            << "lease-seconds = 7.5\n"
                                            << "max-attempts = 9\n"
                                            << "limit = [\"jobs_total=17\", \"jobs_per_client=5\"]\n";
  }
  CoordinatorProcess coordinator(dir / "data", dir.path(),
                                 {"--config", (dir / "coordinator.toml").string(), "--max-attempts", "4"});
  const std::string log = ReadFile(coordinator.process().log());
  EXPECT_NE(log.find("lease 7.5 s"), std::string::npos) << log;
  EXPECT_NE(log.find("max attempts 4 "), std::string::npos) << "the command line wins\n" << log;
  EXPECT_NE(log.find("jobs_per_client=5 jobs_total=17"), std::string::npos) << log;

  { std::ofstream(dir / "bad.toml") << "lease-seconds = 3\nleese-seconds = 4\n"; }
  RunResult r = RunCommand(
      {Binaries::Coordinator(), "--data-dir", (dir / "d2").string(), "--config", (dir / "bad.toml").string()},
      dir.path(), 30);
  EXPECT_EQ(r.exit_code, 2) << r.err;
  EXPECT_NE(r.err.find("leese"), std::string::npos) << r.err;
  r = RunCommand({Binaries::Coordinator(), "--config", (dir / "missing.toml").string()}, dir.path(), 30);
  EXPECT_EQ(r.exit_code, 2) << r.err;
  EXPECT_NE(r.err.find("missing.toml"), std::string::npos) << r.err;
}

// A second coordinator on a port one already serves exits 1; with gRPC's default SO_REUSEPORT it
// used to start, and the kernel split the connections between two coordinators with two data dirs.
TEST(Cli, ASecondCoordinatorOnAPortInUseDoesNotStart) {
  TestDir dir;
  CoordinatorProcess first(dir / "data", dir.path());
  const RunResult r =
      RunCommand({Binaries::Coordinator(), "--listen", "127.0.0.1:" + std::to_string(first.port()),
                  "--data-dir", (dir / "other").string()},
                 dir.path(), 30);
  EXPECT_EQ(r.exit_code, 1) << r.out << r.err;
  EXPECT_NE(r.err.find("cannot listen on 127.0.0.1:" + std::to_string(first.port())), std::string::npos)
      << r.err;
  EXPECT_EQ(r.out.find("listening on"), std::string::npos) << r.out;
}

TEST(Cli, VersionOnAllThreeBinaries) {
  TestDir dir;
  for (const auto& [bin, name] :
       {std::pair{Binaries::Pf(), "pf "}, std::pair{Binaries::Worker(), "pf-worker "},
        std::pair{Binaries::Coordinator(), "pf-coordinator "}}) {
    const RunResult r = RunCommand({bin, "--version"}, dir.path(), 30);
    EXPECT_EQ(r.exit_code, 0) << bin << ": " << r.err;
    EXPECT_EQ(r.out.rfind(std::string(name) + "0.1.0-", 0), 0u) << r.out;
  }
}

TEST(Cli, BogusLogLevelIsAUsageError) {
  TestDir dir;
  RunResult r =
      RunCommand({Binaries::Pf(), "--log-level", "bogus", "info", Binaries::Scene()}, dir.path(), 30);
  EXPECT_EQ(r.exit_code, 2) << r.err;
  // pf-worker used to accept it and then wait for its coordinator forever.
  r = RunCommand({Binaries::Worker(), "--coordinator", "127.0.0.1:1", "--log-level", "bogus"}, dir.path(),
                 20);
  EXPECT_EQ(r.exit_code, 2) << r.err;
}

// The radius schedule is read only by the progressive plan: with another plan pf refuses it
// (exit 2, naming the setting) instead of rendering as if it had not been given.
TEST(Cli, ProgressiveSettingsWithAnotherPlanAreRefused) {
  TestDir dir;
  RunResult r = RunCommand({Binaries::Pf(), "render", Binaries::Scene(), "--integrator", "photonmap", "--set",
                            "progressive-alpha=0.5", "-q", "-o", (dir / "x.exr").string()},
                           dir.path(), 30);
  EXPECT_EQ(r.exit_code, 2) << r.err;
  EXPECT_NE(r.err.find("progressive-alpha"), std::string::npos) << r.err;
  EXPECT_NE(r.err.find("--plan progressive"), std::string::npos) << r.err;
  EXPECT_FALSE(fs::exists(dir / "x.exr"));
}

TEST(Cli, CoordinatorAddressWithoutPortIsRefused) {
  TestDir dir;
  // gRPC would read "localhost" as localhost:443 and retry "nonsense" forever.
  RunResult r =
      RunCommand({Binaries::Pf(), "list", "--coordinator", "localhost", "--timeout", "2"}, dir.path(), 30);
  EXPECT_EQ(r.exit_code, 2) << r.err;
  EXPECT_NE(r.err.find("no port"), std::string::npos) << r.err;
  r = RunCommand({Binaries::Worker(), "--coordinator", "nonsense"}, dir.path(), 20);
  EXPECT_EQ(r.exit_code, 2) << r.err;
  EXPECT_NE(r.err.find("HOST:PORT"), std::string::npos) << r.err;
  r = RunCommand({Binaries::Pf(), "list", "--timeout", "2"}, dir.path(), 30,
                 {{"PF_COORDINATOR", "localhost"}});
  EXPECT_EQ(r.exit_code, 3) << r.err;
  EXPECT_NE(r.err.find("PF_COORDINATOR"), std::string::npos) << r.err;
}

TEST(Cli, OutputMustBeNamedExr) {
  TestDir dir;
  for (const char* name : {"x.png", "x.jpg"}) {
    const RunResult r = RunCommand(TinyRender(Binaries::Scene(), dir / name), dir.path(), 60);
    EXPECT_EQ(r.exit_code, 2) << r.err;
    EXPECT_FALSE(fs::exists(dir / name)) << name;
  }
  const RunResult r =
      RunCommand(Concat(TinyRender(Binaries::Scene(), dir / "x.exr"), {"--png", (dir / "x.exr").string()}),
                 dir.path(), 60);
  EXPECT_EQ(r.exit_code, 2) << r.err;
}

TEST(Cli, UnwritableOutputFailsBeforeTheRender) {
  TestDir dir;
  // A render of many minutes: the error must come at once, not after it.
  const std::vector<std::string> slow = {Binaries::Pf(),
                                         "render",
                                         Binaries::Scene(),
                                         "--spp",
                                         "65536",
                                         "--res",
                                         "512x512",
                                         "-q",
                                         "-o",
                                         (dir / "no-such-folder" / "x.exr").string()};
  RunResult r = RunCommand(slow, dir.path(), 20);
  EXPECT_EQ(r.exit_code, 1) << r.err;
  EXPECT_NE(r.err.find("does not exist"), std::string::npos) << r.err;
  r = RunCommand(Concat(slow, {"--plan", "skipping", "--local-only"}), dir.path(), 20);
  EXPECT_EQ(r.exit_code, 1) << r.err;
}

TEST(Cli, ManifestSettingsAreTheDefaults) {
  TestDir dir;
  const fs::path manifest = WriteManifest(dir.path(), ", \"settings\": {\"spp\": 3}");
  RunResult r = RunCommand(TinyRender(manifest.string(), dir / "a.exr"), dir.path(), 60);
  ASSERT_EQ(r.exit_code, 0) << r.err;
  EXPECT_EQ(HeaderOf(dir / "a.exr")["spp"], "1") << "--spp given: the flag wins";
  r = RunCommand({Binaries::Pf(), "render", manifest.string(), "--res", "8x8", "-q", "--no-png", "-o",
                  (dir / "b.exr").string()},
                 dir.path(), 60);
  ASSERT_EQ(r.exit_code, 0) << r.err;
  EXPECT_EQ(HeaderOf(dir / "b.exr")["spp"], "3") << r.err;
}

TEST(Cli, RenderShowsManifestWarnings) {
  TestDir dir;
  const fs::path manifest = WriteManifest(dir.path(), ", \"colour_grading\": 1");
  const RunResult r = RunCommand(TinyRender(manifest.string(), dir / "a.exr"), dir.path(), 60);
  ASSERT_EQ(r.exit_code, 0) << r.err;
  EXPECT_NE(r.err.find("colour_grading"), std::string::npos) << r.err;
}

// A scene without any light would render black: exit 3 (bad input), naming the file and why —
// here tinyobjloader's cornell_box.obj case, a lamp with only Ka.
TEST(Cli, SceneWithoutLightIsBadInput) {
  TestDir dir;
  std::ofstream(dir / "ka.mtl") << "newmtl lamp\nKa 20 20 20\nKd 0.5 0.5 0.5\n";
  std::ofstream(dir / "ka.obj") << "mtllib ka.mtl\nv 0 0 0\nv 1 0 0\nv 0 1 0\nusemtl lamp\nf 1 2 3\n";
  const RunResult r = RunCommand(TinyRender((dir / "ka.obj").string(), dir / "a.exr"), dir.path(), 60);
  EXPECT_EQ(r.exit_code, 3) << r.err;
  EXPECT_NE(r.err.find("ka.obj"), std::string::npos) << r.err;
  EXPECT_NE(r.err.find("the scene has no light"), std::string::npos) << r.err;
  EXPECT_NE(r.err.find("Ka is not emission in pf; use Ke"), std::string::npos) << r.err;
  EXPECT_FALSE(fs::exists(dir / "a.exr"));
  // The same geometry with a manifest light renders.
  std::ofstream(dir / "lit.json")
      << R"({"geometry": "ka.obj", "lights": [{"type": "point", "position": [0.2, 0.2, 1]}],
      "cameras": [{"eye": [0.3, 0.3, 2], "look_at": [0.3, 0.3, 0]}]})";
  const RunResult lit = RunCommand(TinyRender((dir / "lit.json").string(), dir / "b.exr"), dir.path(), 60);
  EXPECT_EQ(lit.exit_code, 0) << lit.err;
}

TEST(Cli, FlagLimitsAreTheFarmsLimits) {
  TestDir dir;
  const std::vector<std::string> base = TinyRender(Binaries::Scene(), dir / "a.exr");
  // Accepted by pf before (its own limits 10^5, 2^31), refused by every coordinator.
  RunResult r = RunCommand(Concat(base, {"--k", "20000"}), dir.path(), 60);
  EXPECT_EQ(r.exit_code, 2) << r.err;
  r = RunCommand(Concat(base, {"--photons", "300000000"}), dir.path(), 60);
  EXPECT_EQ(r.exit_code, 2) << r.err;
  r = RunCommand(
      {Binaries::Pf(), "render", Binaries::Scene(), "--res", "9000x8", "-o", (dir / "b.exr").string()},
      dir.path(), 60);
  EXPECT_EQ(r.exit_code, 3) << r.err;
  r = RunCommand({Binaries::Pf(), "--help"}, dir.path(), 30);
  EXPECT_NE(r.out.find("--photons <= 268435456"), std::string::npos) << r.out;
  EXPECT_NE(r.out.find("--k <= 10000"), std::string::npos) << r.out;
}

// One task cap (proto/limits.h, 2^20). A local plan of 2^20 + 1 = 17 x 61681 tasks is
// refused at once (exit 3) with the farm's message; it used to start rendering (the plan code
// allowed 2^24, the coordinator 2^20).
TEST(Cli, LocalPlanTaskCapIsTheFarms) {
  TestDir dir;
  const RunResult r = RunCommand(
      {Binaries::Pf(), "render", Binaries::Scene(), "--plan", "multiple-maps", "--maps", "61681", "--tile",
       "1", "--res", "17x1", "--local-only", "-o", (dir / "cap.exr").string(), "--no-png", "-q"},
      dir.path(), 30);
  EXPECT_EQ(r.exit_code, 3) << r.err;
  EXPECT_NE(r.err.find("spec.plan: 1048577 tasks exceed the limit of 1048576 per job"), std::string::npos)
      << r.err;
  EXPECT_FALSE(std::filesystem::exists(dir / "cap.exr"));
}

TEST(Cli, PlainRenderRefusesPlanOptions) {
  TestDir dir;
  for (const std::vector<std::string>& extra :
       {std::vector<std::string>{"--stride", "4"}, {"--maps", "5"}, {"--rounds", "2"}}) {
    const RunResult r = RunCommand(
        Concat(Concat(TinyRender(Binaries::Scene(), dir / "a.exr"), {"--integrator", "path"}), extra),
        dir.path(), 60);
    EXPECT_EQ(r.exit_code, 2) << extra[0] << ": " << r.err;
    EXPECT_NE(r.err.find("plan renders only"), std::string::npos) << r.err;
  }
}

// A photon-map option with the path tracer was silently ignored; now it is a usage error that
// names the option (render and submit alike).
TEST(Cli, PathTracerRefusesPhotonMapOptions) {
  TestDir dir;
  for (const std::vector<std::string>& extra :
       {std::vector<std::string>{"--photons", "1000"}, {"--caustic-split", "4"}, {"--occlusion-test"}}) {
    const RunResult r = RunCommand(
        Concat(Concat(TinyRender(Binaries::Scene(), dir / "a.exr"), {"--integrator", "path"}), extra),
        dir.path(), 60);
    EXPECT_EQ(r.exit_code, 2) << extra[0] << ": " << r.err;
    EXPECT_NE(r.err.find(extra[0]), std::string::npos) << r.err;
    EXPECT_NE(r.err.find("photon-map integrator only"), std::string::npos) << r.err;
  }
  const RunResult ok = RunCommand(Concat(TinyRender(Binaries::Scene(), dir / "b.exr"),
                                         {"--integrator", "photonmap", "--photons", "1000"}),
                                  dir.path(), 120);
  EXPECT_EQ(ok.exit_code, 0) << ok.err;
}

// A mistyped subcommand or option names the closest known one (edit distance).
TEST(Cli, DidYouMeanForUnknownSubcommandsAndOptions) {
  TestDir dir;
  RunResult r = RunCommand({Binaries::Pf(), "rendr", Binaries::Scene()}, dir.path(), 30);
  EXPECT_EQ(r.exit_code, 2) << r.err;
  EXPECT_NE(r.err.find("did you mean 'render'?"), std::string::npos) << r.err;
  r = RunCommand(Concat(TinyRender(Binaries::Scene(), dir / "a.exr"), {"--photon", "10"}), dir.path(), 30);
  EXPECT_EQ(r.exit_code, 2) << r.err;
  EXPECT_NE(r.err.find("'--photon': did you mean '--photons'?"), std::string::npos) << r.err;
  // Nothing close: no guess.
  r = RunCommand({Binaries::Pf(), "xyzzy-frobnicate"}, dir.path(), 30);
  EXPECT_EQ(r.exit_code, 2) << r.err;
  EXPECT_EQ(r.err.find("did you mean"), std::string::npos) << r.err;
}

TEST(Cli, MergeWeighsBySppAndWarns) {
  TestDir dir;
  for (const char* name : {"a.exr", "b.exr"})
    ASSERT_EQ(RunCommand(TinyRender(Binaries::Scene(), dir / name), dir.path(), 60).exit_code, 0);
  ASSERT_EQ(RunCommand(Concat(TinyRender(Binaries::Scene(), dir / "pm.exr"),
                              {"--integrator", "photonmap", "--photons", "2000", "--k", "10"}),
                       dir.path(), 60)
                .exit_code,
            0);
  // The same seed twice: warned.
  RunResult r = RunCommand({Binaries::Pf(), "merge", (dir / "a.exr").string(), (dir / "b.exr").string(), "-o",
                            (dir / "ab.exr").string()},
                           dir.path(), 60);
  EXPECT_EQ(r.exit_code, 0) << r.err;
  EXPECT_NE(r.err.find("seed 1"), std::string::npos) << r.err;
  // The integrator `auto` chose, and why, carry over when every input says the same.
  const std::string chosen = HeaderOf(dir / "a.exr")["auto.integrator"];
  EXPECT_EQ(chosen.rfind("path: ", 0), 0u) << chosen;
  EXPECT_EQ(HeaderOf(dir / "ab.exr")["auto.integrator"], chosen);
  // Different integrators: warned.
  r = RunCommand({Binaries::Pf(), "merge", (dir / "a.exr").string(), (dir / "pm.exr").string(), "-o",
                  (dir / "apm.exr").string()},
                 dir.path(), 60);
  EXPECT_EQ(r.exit_code, 0) << r.err;
  EXPECT_NE(r.err.find("integrator"), std::string::npos) << r.err;
  EXPECT_EQ(HeaderOf(dir / "apm.exr").count("auto.integrator"), 0u) << "not every input's choice";
  // An EXR without spp (here pf diff's error image) is not silently weighted 1.
  ASSERT_EQ(RunCommand({Binaries::Pf(), "diff", (dir / "a.exr").string(), (dir / "b.exr").string(),
                        "--error-image", (dir / "err.exr").string()},
                       dir.path(), 60)
                .exit_code,
            0);
  r = RunCommand({Binaries::Pf(), "merge", (dir / "a.exr").string(), (dir / "err.exr").string(), "-o",
                  (dir / "m.exr").string()},
                 dir.path(), 60);
  EXPECT_EQ(r.exit_code, 3) << r.err;
  EXPECT_NE(r.err.find("--assume-spp"), std::string::npos) << r.err;
  r = RunCommand({Binaries::Pf(), "merge", (dir / "a.exr").string(), (dir / "err.exr").string(),
                  "--assume-spp", "1", "-o", (dir / "m.exr").string()},
                 dir.path(), 60);
  EXPECT_EQ(r.exit_code, 0) << r.err;
  EXPECT_EQ(HeaderOf(dir / "m.exr")["spp"], "2");
}

TEST(Cli, InfoPrintsAnExrHeader) {
  TestDir dir;
  ASSERT_EQ(RunCommand(TinyRender(Binaries::Scene(), dir / "a.exr"), dir.path(), 60).exit_code, 0);
  const RunResult r = RunCommand({Binaries::Pf(), "info", (dir / "a.exr").string()}, dir.path(), 30);
  ASSERT_EQ(r.exit_code, 0) << r.err;
  for (const char* key : {"size        8x8", "seed", "camera.eye", "integrator", "version", "date"})
    EXPECT_NE(r.out.find(key), std::string::npos) << key << "\n" << r.out;
}

// The choices an `auto` setting makes for a scene, as pf render and the coordinator log them.
TEST(Cli, InfoOfASceneSaysWhatAutoWouldChoose) {
  TestDir dir;
  const RunResult r = RunCommand({Binaries::Pf(), "info", Binaries::Scene()}, dir.path(), 30);
  ASSERT_EQ(r.exit_code, 0) << r.err;
  EXPECT_NE(r.out.find("auto        caustic-map = "), std::string::npos) << r.out;
  EXPECT_NE(r.out.find("auto        direct = monte-carlo: 1 light (< 8)"), std::string::npos) << r.out;
}

// `--integrator auto`, pf render's and pf submit's default (docs/renderer.md, "Choosing the
// integrator"): chosen from the scene and a pilot, logged, and recorded with its reason in the
// image header; a setting only the photon map reads asks for it; a named integrator is no choice.
TEST(Cli, IntegratorAutoChoosesFromTheSceneAndTheHeaderSaysWhy) {
  TestDir dir;
  const fs::path scenes = fs::path(Binaries::Scene()).parent_path().parent_path();
  const auto render = [&](const std::string& scene, const std::vector<std::string>& extra) {
    const fs::path out = dir / "auto.exr";
    const RunResult r = RunCommand(Concat(TinyRender(scene, out), extra), dir.path(), 120);
    EXPECT_EQ(r.exit_code, 0) << r.err;
    return std::pair{HeaderOf(out), r.err};
  };
  {
    const auto [header, log] = render(Binaries::Scene(), {});
    EXPECT_EQ(header.at("settings.integrator"), "path");
    EXPECT_EQ(header.at("auto.integrator").rfind("path: ", 0), 0u) << header.at("auto.integrator");
    EXPECT_NE(header.at("auto.integrator").find("lit directly"), std::string::npos);
    EXPECT_NE(log.find("auto integrator = path"), std::string::npos) << log;
  }
  {
    const auto [header, log] = render((scenes / "cornell-sphere/cornell-sphere.json").string(), {});
    EXPECT_EQ(header.at("settings.integrator"), "photonmap");
    EXPECT_NE(header.at("auto.integrator").find("mirror or glass"), std::string::npos);
    EXPECT_EQ(header.count("auto.caustic-map"), 1u) << "the photon map's own auto settings follow";
  }
  {
    const auto [header, log] = render(Binaries::Scene(), {"--set", "k=30"});
    EXPECT_EQ(header.at("settings.integrator"), "photonmap");
    EXPECT_NE(header.at("auto.integrator").find("settings only the photon map reads"), std::string::npos);
  }
  {
    const auto [header, log] =
        render((scenes / "cornell-sphere/cornell-sphere.json").string(), {"--integrator", "path"});
    EXPECT_EQ(header.at("settings.integrator"), "path");
    EXPECT_EQ(header.count("auto.integrator"), 0u) << "forced, not chosen";
  }
}

}  // namespace
}  // namespace pf::e2e
