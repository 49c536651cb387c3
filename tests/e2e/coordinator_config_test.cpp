// pf-coordinator --config FILE (deploy/README.md, docs/farm.md "Coordinator"), real processes:
//  - a coordinator started with nothing but --config (listen, data dir, both token files, the maps
//    quota, retention, a limit) serves a farm: a worker with the worker token renders a job that
//    pf submitted with the client token, bit-identical to a local render;
//  - a bad value is refused naming its key (exit 2), as an unknown key is (cli_test.cpp);
//  - the shipped deploy/coordinator.toml is accepted as written (its credential paths and
//    addresses overridden on the command line), and the copy deploy/make-credentials.sh writes from
//    it starts a TLS + mTLS coordinator with its settings.
#include <gtest/gtest.h>

#include <fstream>
#include <sstream>

#include "client/farm_client.h"
#include "tests/e2e/harness.h"

namespace pf::e2e {
namespace {
namespace fs = std::filesystem;
namespace v1 = photonfarm::v1;

std::vector<std::string> SmallJob() {
  return {"--integrator", "photonmap",     "--photons", "8192", "--k",    "20",
          "--plan",       "multiple-maps", "--maps",    "2",    "--tile", "8",
          "--res",        "16x8",          "--spp",     "1",    "--seed", "11"};
}

std::string Log(CoordinatorProcess& c) {
  return ReadFile(c.process().log());
}

TEST(CoordinatorConfig, ACoordinatorStartedWithOnlyAConfigFileServesAFarm) {
  TestDir dir;
  ASSERT_EQ(RenderLocally(dir, SmallJob()).exit_code, 0);
  const Image reference = ReadImage(dir / "local.exr");
  std::ofstream(dir / "client-token") << "client-secret-1234567890\n";
  std::ofstream(dir / "worker-token") << "worker-secret-0987654321\n";
  {
    std::ofstream toml(dir / "farm.toml");
    toml << "# the whole coordinator in one file\n"
         << "listen = \"127.0.0.1:0\"\n"
         << "data-dir = \"" << (dir / "data").string() << "\"\n"
         << "client-token-file = \"" << (dir / "client-token").string() << "\"\n"
         << "worker-token-file = \"" << (dir / "worker-token").string() << "\"\n"
         << "maps-quota = \"64M\"\n"
         << "retain-finished = \"2d\"\n"
         << "verify-fraction = 0\n"
         << "limit = [\"jobs_per_client=5\"]\n";
  }
  CoordinatorProcess coordinator(CoordinatorProcess::ConfigFileOnly{}, dir / "farm.toml", dir.path());
  const std::string log = Log(coordinator);
  EXPECT_NE(log.find("data dir " + (dir / "data").string()), std::string::npos) << log;
  EXPECT_NE(log.find("client token required, worker token required"), std::string::npos) << log;
  EXPECT_NE(log.find("map store: quota 67108864 bytes"), std::string::npos) << log;
  EXPECT_NE(log.find("finished jobs retained 172800 s"), std::string::npos) << log;
  EXPECT_NE(log.find("jobs_per_client=5"), std::string::npos) << log;
  EXPECT_TRUE(fs::exists(dir / "data" / "coordinator.db"));

  const std::string id = SubmitJob(
      dir, coordinator.address(),
      Concat(SmallJob(), {"--map-tracing", "distributed", "--token-file", (dir / "client-token").string()}));
  ASSERT_FALSE(id.empty());
  auto worker =
      StartWorker(coordinator.address(), dir.path(), "w1", {"--token-file", (dir / "worker-token").string()});
  FarmClient client(coordinator.address(), "client-secret-1234567890");
  const v1::JobStatus st = WaitForJob(client, id, 120);
  ASSERT_EQ(st.state(), v1::JOB_STATE_SUCCEEDED) << st.failure_reason() << "\n" << ReadFile(dir / "w1.log");
  EXPECT_TRUE(BitIdentical(DecodeImage(client.GetImage(id)), reference));
}

TEST(CoordinatorConfig, ABadValueIsAUsageErrorNamingItsKey) {
  TestDir dir;
  for (const auto& [line, key] : std::vector<std::pair<std::string, std::string>>{
           {"maps-quota = \"lots\"", "--maps-quota"},
           {"retain-finished = \"7 weeks\"", "--retain-finished"},
           {"max-attempts = 0", "--max-attempts"},
           {"mapsquota = \"2G\"", "mapsquota"}}) {
    SCOPED_TRACE(line);
    { std::ofstream(dir / "bad.toml") << "listen = \"127.0.0.1:0\"\n" << line << "\n"; }
    const RunResult r = RunCommand({Binaries::Coordinator(), "--config", (dir / "bad.toml").string(),
                                    "--data-dir", (dir / "data").string()},
                                   dir.path(), 30);
    EXPECT_EQ(r.exit_code, 2) << r.out << r.err;
    EXPECT_NE(r.err.find(key), std::string::npos) << r.err;
    EXPECT_EQ(r.out.find("listening on"), std::string::npos) << r.out;
  }
}

TEST(CoordinatorConfig, TheShippedConfigIsAcceptedAndMakeCredentialsWritesItForItsFolder) {
  TestDir dir;
  const fs::path shipped = fs::path(PF_SOURCE_DIR) / "deploy" / "coordinator.toml";
  const fs::path etc = dir / "etc";
  const RunResult made =
      RunCommand({"/bin/bash", (fs::path(PF_SOURCE_DIR) / "deploy" / "make-credentials.sh").string(),
                  "--port", "7123", "--http-port", "8123", etc.string()},
                 dir.path(), 120);
  ASSERT_EQ(made.exit_code, 0) << made.err;

  // The written copy is the shipped file with the folder's paths and ports, line for line.
  std::istringstream shipped_lines(ReadFile(shipped)), written_lines(ReadFile(etc / "coordinator.toml"));
  std::string a, b;
  size_t settings = 0;
  while (std::getline(shipped_lines, a)) {
    ASSERT_TRUE(std::getline(written_lines, b)) << "the copy ends early";
    std::string expected = a;
    for (size_t at; (at = expected.find("/etc/photonfarm")) != std::string::npos;)
      expected.replace(at, 15, etc.string());
    if (expected == "listen = \"0.0.0.0:7000\"") expected = "listen = \"0.0.0.0:7123\"";
    if (expected == "http = \"0.0.0.0:8080\"") expected = "http = \"0.0.0.0:8123\"";
    EXPECT_EQ(b, expected);
    settings += !a.empty() && a[0] != '#';
  }
  EXPECT_GE(settings, 10u) << "the shipped file sets what a deployment needs";

  const std::vector<std::string> local = {"--listen", "127.0.0.1:0", "--http", "127.0.0.1:0", "--data-dir"};
  auto expect_settings = [](const std::string& log) {
    EXPECT_NE(log.find("TLS + client certificates for workers, client token required, worker token required"),
              std::string::npos)
        << log;
    EXPECT_NE(log.find("map store: quota 21474836480 bytes"), std::string::npos) << log;
    EXPECT_NE(log.find("finished jobs retained 2592000 s"), std::string::npos) << log;
  };
  {
    // The shipped file itself: every key known, every value valid; its credentials are in etc here.
    CoordinatorProcess coordinator(
        CoordinatorProcess::ConfigFileOnly{}, shipped, dir.path(),
        Concat(Concat(local, {(dir / "data1").string()}),
               {"--tls-cert", (etc / "coordinator.pem").string(), "--tls-key",
                (etc / "coordinator.key").string(), "--tls-client-ca", (etc / "ca.pem").string(),
                "--client-token-file", (etc / "client-token").string(), "--worker-token-file",
                (etc / "worker-token").string()}));
    expect_settings(Log(coordinator));
    EXPECT_GT(coordinator.http_port(), 0);
  }
  CoordinatorProcess coordinator(CoordinatorProcess::ConfigFileOnly{}, etc / "coordinator.toml", dir.path(),
                                 Concat(local, {(dir / "data2").string()}));
  expect_settings(Log(coordinator));
}

}  // namespace
}  // namespace pf::e2e
