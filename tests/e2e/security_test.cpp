// Hardening (issue #14) against a real coordinator: hostile scene bundles uploaded through the
// real client library. A bundle may refer only to its own files (scene_reference.h); the answer
// is INVALID_ARGUMENT naming file:line, echoing nothing of the coordinator's files, with no
// server path, and the same whether the outside file exists or not.
#include <fstream>

#include "client/farm_client.h"
#include "common/scene/scene_bundle.h"
#include "tests/e2e/harness.h"

namespace pf::e2e {
namespace {
namespace fs = std::filesystem;

constexpr const char* kQuadMgf =
    "m white =\n  c\n  rd .5\n  ed 10\n"
    "v a =\n p 0 0 0\nv b =\n p 1 0 0\nv c =\n p 1 1 0\nv d =\n p 0 1 0\n"
    "f a b c d\n";
constexpr const char* kQuadObj = "v 0 0 0\nv 1 0 0\nv 1 1 0\nf 1 2 3\n";

// The status of an upload that must fail.
grpc::Status UploadFailure(FarmClient& client, const SceneBundle& bundle) {
  try {
    client.UploadScene(bundle);
  } catch (const RpcError& e) {
    return e.status();
  }
  return grpc::Status::OK;
}

SceneBundle OneFile(const std::string& name, const std::string& content) {
  SceneBundle b;
  b.entry = name;
  b.files = {{name, content}};
  return b;
}

class BundleConfinement : public ::testing::Test {
 protected:
  void SetUp() override {
    coordinator_ = std::make_unique<CoordinatorProcess>(dir_ / "data", dir_.path());
    client_ = std::make_unique<FarmClient>(coordinator_->address(), "");
    // Files of the coordinator's host that a bundle must not reach. Their words would come
    // back as "unknown entity" warnings (MGF) or as materials (MTL) if they were read.
    fs::create_directories(dir_ / "host");
    std::ofstream(dir_ / "host" / "secret.mgf") << "HOSTSECRET one two\n";
    std::ofstream(dir_ / "host" / "secret.obj") << kQuadObj;
    std::ofstream(dir_ / "host" / "secret.mtl") << "newmtl HOSTSECRET\nKd 1 0 0\n";
  }
  // "../" deep enough to climb from anywhere in the data folder to "/", then the host path.
  std::string Climb(const std::string& name) const {
    std::string up;
    for (int i = 0; i < 40; ++i) up += "../";
    return up + (dir_ / "host" / name).relative_path().string();
  }
  // Uploads `bundle`; expects INVALID_ARGUMENT containing `where` and nothing of the host.
  std::string ExpectRefused(const SceneBundle& bundle, const std::string& where) {
    const grpc::Status st = UploadFailure(*client_, bundle);
    EXPECT_EQ(st.error_code(), grpc::StatusCode::INVALID_ARGUMENT) << st.error_message();
    EXPECT_NE(st.error_message().find(where), std::string::npos) << st.error_message();
    EXPECT_EQ(st.error_message().find("HOSTSECRET"), std::string::npos) << st.error_message();
    EXPECT_EQ(st.error_message().find((dir_ / "data").string()), std::string::npos)
        << "server path in: " << st.error_message();
    return st.error_message();
  }

  TestDir dir_;
  std::unique_ptr<CoordinatorProcess> coordinator_;
  std::unique_ptr<FarmClient> client_;
};

TEST_F(BundleConfinement, MgfIncludeOutsideTheBundleIsRefused) {
  const std::string existing = ExpectRefused(
      OneFile("main.mgf", std::string(kQuadMgf) + "i " + Climb("secret.mgf") + "\n"), "main.mgf:14: include");
  const std::string missing =
      ExpectRefused(OneFile("main.mgf", std::string(kQuadMgf) + "i " + Climb("nothere.mgf") + "\n"),
                    "main.mgf:14: include");
  // No existence oracle: both answers agree apart from the reference itself.
  EXPECT_EQ(existing.substr(existing.find("resolves")), missing.substr(missing.find("resolves")));
  ExpectRefused(OneFile("main.mgf", "i " + (dir_ / "host" / "secret.mgf").string() + "\n"),
                "main.mgf:1: include");
  ExpectRefused(OneFile("main.mgf", "i ../main.mgf\n"), "main.mgf:1: include '../main.mgf' resolves outside");
}

TEST_F(BundleConfinement, ManifestGeometryOutsideTheBundleIsRefused) {
  ExpectRefused(OneFile("s.json", "{\n\"geometry\": \"" + (dir_ / "host" / "secret.obj").string() + "\"}"),
                "s.json:2: key 'geometry'");
  const std::string existing = ExpectRefused(
      OneFile("s.json", "{\"geometry\": \"" + Climb("secret.obj") + "\"}"), "s.json:1: key 'geometry'");
  const std::string missing = ExpectRefused(
      OneFile("s.json", "{\"geometry\": \"" + Climb("nothere.obj") + "\"}"), "s.json:1: key 'geometry'");
  EXPECT_EQ(existing.substr(existing.find("resolves")), missing.substr(missing.find("resolves")));
}

TEST_F(BundleConfinement, ObjMtllibOutsideTheBundleIsRefused) {
  ExpectRefused(OneFile("m.obj", "mtllib " + Climb("secret.mtl") + "\nusemtl HOSTSECRET\n" + kQuadObj),
                "m.obj:1: mtllib");
  ExpectRefused(OneFile("m.obj", "mtllib " + (dir_ / "host" / "secret.mtl").string() + "\n" + kQuadObj),
                "m.obj:1: mtllib");
}

TEST_F(BundleConfinement, AFileThatIsAlsoAFolderIsInvalidArgument) {
  SceneBundle b = OneFile("main.mgf", kQuadMgf);
  b.files.emplace_back("a", "x");
  b.files.emplace_back("a/b", "y");
  ExpectRefused(b, "'a' is also a file of the bundle");
  // The bundle's own files still load: a valid upload works after the refusals.
  EXPECT_EQ(client_->UploadScene(OneFile("main.mgf", kQuadMgf)).triangles(), 2u);
}

}  // namespace
}  // namespace pf::e2e
