// Hardening (docs/security.md) against a real coordinator: hostile scene bundles uploaded through the
// real client library. A bundle may refer only to its own files (scene_reference.h); the answer
// is INVALID_ARGUMENT naming file:line, echoing nothing of the coordinator's files, with no
// server path, and the same whether the outside file exists or not.
#include <httplib.h>
#include <signal.h>
#include <unistd.h>

#include <fstream>

#include "client/farm_client.h"
#include "common/scene/scene_bundle.h"
#include "tests/e2e/harness.h"
#include "tests/util/job_specs.h"

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

// The openssl CLI on $PATH (tools/install-deps.sh installs it); the harness execs by path.
std::string OpensslBinary() {
  const char* path = std::getenv("PATH");
  std::string dirs = path ? path : "/usr/bin:/bin";
  for (size_t begin = 0; begin <= dirs.size();) {
    const size_t end = std::min(dirs.find(':', begin), dirs.size());
    const fs::path candidate = fs::path(dirs.substr(begin, end - begin)) / "openssl";
    if (::access(candidate.c_str(), X_OK) == 0) return candidate.string();
    begin = end + 1;
  }
  return "/usr/bin/openssl";
}

// TLS and mTLS with certificates made here by the openssl CLI: a CA, the coordinator's
// certificate (SAN 127.0.0.1 and localhost) and a worker's client certificate. The coordinator
// also serves its status page on every address (0.0.0.0), which TLS allows.
class TlsFarm : public ::testing::Test {
 protected:
  void SetUp() override {
    MakeCa("ca", "photonfarm test CA");
    MakeCertificate("server", "ca", "2", /*server=*/true);
    MakeCertificate("worker", "ca", "2");
    std::ofstream(dir_ / "client-token") << "tls-client-token\n";
    std::ofstream(dir_ / "worker-token") << "tls-worker-token\n";
    coordinator_ = std::make_unique<CoordinatorProcess>(
        dir_ / "data", dir_.path(),
        std::vector<std::string>{"--tls-cert", Path("server.pem"), "--tls-key", Path("server.key"),
                                 "--tls-client-ca", Path("ca.pem"), "--worker-token-file",
                                 Path("worker-token"), "--http", "0.0.0.0:0"},
        0, Path("client-token"));
  }
  std::string Path(const std::string& name) const { return (dir_ / name).string(); }
  void Openssl(std::vector<std::string> args) {
    args.insert(args.begin(), OpensslBinary());
    const RunResult r = RunCommand(args, dir_.path(), 60);
    ASSERT_EQ(r.exit_code, 0) << r.err;
  }
  // <name>.pem and <name>.key: a self-signed CA.
  void MakeCa(const std::string& name, const std::string& common_name) {
    Openssl({"req", "-x509", "-newkey", "rsa:2048", "-nodes", "-keyout", Path(name + ".key"), "-out",
             Path(name + ".pem"), "-days", "2", "-subj", "/CN=" + common_name});
  }
  // <name>.pem and <name>.key, signed by the CA <ca>, valid from now for `days` days (negative:
  // expired that many days ago); a server certificate names 127.0.0.1 and localhost.
  void MakeCertificate(const std::string& name, const std::string& ca, const std::string& days,
                       bool server = false) {
    Openssl({"req", "-newkey", "rsa:2048", "-nodes", "-keyout", Path(name + ".key"), "-out",
             Path(name + ".csr"), "-subj", "/CN=" + name});
    std::vector<std::string> sign = {"x509",
                                     "-req",
                                     "-in",
                                     Path(name + ".csr"),
                                     "-CA",
                                     Path(ca + ".pem"),
                                     "-CAkey",
                                     Path(ca + ".key"),
                                     "-CAcreateserial",
                                     "-out",
                                     Path(name + ".pem"),
                                     "-days",
                                     days};
    if (server) {
      std::ofstream(dir_ / "san.cnf") << "subjectAltName=DNS:localhost,IP:127.0.0.1\n";
      sign.insert(sign.end(), {"-extfile", Path("san.cnf")});
    }
    Openssl(sign);
  }
  ClientTls CaOnly() const { return ResolveClientTls(Path("ca.pem"), "", ""); }

  TestDir dir_;
  std::unique_ptr<CoordinatorProcess> coordinator_;
};

TEST_F(TlsFarm, ClientsNeedTlsAndTheirToken) {
  FarmClient tls(coordinator_->address(), "tls-client-token", 10, CaOnly());
  EXPECT_TRUE(tls.ListJobs(true).empty());
  // A plaintext client is refused by the TLS coordinator (the handshake fails: UNAVAILABLE).
  FarmClient plain(coordinator_->address(), "tls-client-token", 5);
  try {
    plain.ListJobs(true);
    ADD_FAILURE() << "a plaintext client was served";
  } catch (const RpcError& e) {
    EXPECT_EQ(e.code(), grpc::StatusCode::UNAVAILABLE) << e.what();
  }
  // The worker's credential does not open RenderService.
  FarmClient as_worker(coordinator_->address(), "tls-worker-token", 10, CaOnly());
  try {
    as_worker.ListJobs(true);
    ADD_FAILURE() << "the worker token listed jobs";
  } catch (const RpcError& e) {
    EXPECT_EQ(e.code(), grpc::StatusCode::PERMISSION_DENIED) << e.what();
  }
  // pf itself, with --tls-ca.
  const RunResult r = RunCommand({Binaries::Pf(), "list", "--coordinator", coordinator_->address(),
                                  "--tls-ca", Path("ca.pem"), "--token-file", Path("client-token")},
                                 dir_.path(), 30);
  EXPECT_EQ(r.exit_code, 0) << r.err;
}

TEST_F(TlsFarm, WorkersNeedAClientCertificate) {
  // Without a client certificate: refused on every WorkerService call, says why, keeps trying.
  auto no_cert = StartWorker(coordinator_->address(), dir_.path(), "w-nocert",
                             {"--tls-ca", Path("ca.pem"), "--token-file", Path("worker-token")});
  EXPECT_TRUE(WaitUntil([&] { return !Grep(no_cert->log(), "client certificate").empty(); }, 15))
      << ReadFile(no_cert->log());
  // Listed as refused, with the reason, under the id it announced (docs/farm.md "Worker health"):
  // refused inside gRPC before its request was read, where the address is not known.
  FarmClient client(coordinator_->address(), "tls-client-token", 10, CaOnly());
  const auto listed = [&](const std::string& id, const std::string& peer, const std::string& reason) {
    for (const photonfarm::v1::WorkerInfo& w : client.ListWorkers())
      if (w.worker_id() == id && w.refused() && w.peer() == peer &&
          w.refused_reason().find(reason) != std::string::npos)
        return true;
    return false;
  };
  EXPECT_TRUE(listed("w-nocert", "", "needs a client certificate"));
  no_cert->Signal(SIGTERM);
  no_cert->Wait(10);
  // With a certificate and a wrong token: refused by the handlers' gate, counted at its address.
  { std::ofstream(Path("wrong-token")) << "guess\n"; }
  auto wrong_token = StartWorker(coordinator_->address(), dir_.path(), "w-badtoken",
                                 {"--tls-ca", Path("ca.pem"), "--tls-cert", Path("worker.pem"), "--tls-key",
                                  Path("worker.key"), "--token-file", Path("wrong-token")});
  EXPECT_TRUE(WaitUntil([&] { return listed("w-badtoken", "127.0.0.1", "invalid bearer token"); }, 15))
      << ReadFile(wrong_token->log());
  wrong_token->Signal(SIGTERM);
  wrong_token->Wait(10);

  // With it, a job renders end to end over mTLS.
  auto worker = StartWorker(coordinator_->address(), dir_.path(), "w-mtls",
                            {"--tls-ca", Path("ca.pem"), "--tls-cert", Path("worker.pem"), "--tls-key",
                             Path("worker.key"), "--token-file", Path("worker-token")});
  JobArgs job;
  job.rounds = 1;
  const std::vector<std::string> at = {"--coordinator", coordinator_->address(), "--tls-ca",
                                       Path("ca.pem"),  "--token-file",          Path("client-token")};
  RunResult r = RunCommand(Concat(Concat({Binaries::Pf(), "submit", Binaries::Scene()}, job.ToFlags()), at),
                           dir_.path());
  ASSERT_EQ(r.exit_code, 0) << r.err;
  const std::string id = r.out.substr(0, r.out.find('\n'));
  r = RunCommand(Concat({Binaries::Pf(), "watch", id, "-q", "-o", Path("tls.exr")}, at), dir_.path(), 120);
  EXPECT_EQ(r.exit_code, 0) << r.err << ReadFile(worker->log());
  EXPECT_EQ(ReadImage(dir_ / "tls.exr").width(), job.res);
}

// A client or worker whose certificate the coordinator refuses is told so, not "unreachable"
// (rpc/tls_diagnosis.h); the exit code stays 1 (a runtime failure).
TEST_F(TlsFarm, RefusedCertificatesAreNamedNotUnreachable) {
  MakeCertificate("expired", "ca", "-1");  // the right CA, but its validity ended a day ago
  MakeCa("other-ca", "other test CA");
  MakeCertificate("foreign", "other-ca", "2");
  const std::string refused = "TLS handshake with " + coordinator_->address() +
                              " failed: the coordinator refused this client's certificate";
  for (const auto& [who, why] : std::vector<std::pair<std::string, std::string>>{
           {"expired", "it expired on "},
           {"foreign",
            "it is signed by 'CN=other test CA', another CA than the one the coordinator accepts "
            "('CN=photonfarm test CA'"}}) {
    const RunResult r = RunCommand({Binaries::Pf(), "list", "--coordinator", coordinator_->address(),
                                    "--tls-ca", Path("ca.pem"), "--tls-cert", Path(who + ".pem"), "--tls-key",
                                    Path(who + ".key"), "--token-file", Path("client-token")},
                                   dir_.path(), 30);
    EXPECT_EQ(r.exit_code, 1) << r.err;
    EXPECT_NE(r.err.find(refused), std::string::npos) << who << ": " << r.err;
    EXPECT_NE(r.err.find(why), std::string::npos) << who << ": " << r.err;
  }
  // This side refusing the coordinator's certificate says that instead.
  MakeCa("unrelated-ca", "unrelated CA");
  RunResult r = RunCommand({Binaries::Pf(), "list", "--coordinator", coordinator_->address(), "--tls-ca",
                            Path("unrelated-ca.pem"), "--token-file", Path("client-token")},
                           dir_.path(), 30);
  EXPECT_EQ(r.exit_code, 1) << r.err;
  EXPECT_NE(r.err.find("this client does not trust the coordinator's certificate"), std::string::npos)
      << r.err;
  // A worker logs the reason and keeps trying.
  auto worker = StartWorker(coordinator_->address(), dir_.path(), "w-expired",
                            {"--tls-ca", Path("ca.pem"), "--tls-cert", Path("expired.pem"), "--tls-key",
                             Path("expired.key"), "--token-file", Path("worker-token")});
  EXPECT_TRUE(WaitUntil(
      [&] { return !Grep(worker->log(), "refused this client's certificate.*expired on").empty(); }, 15))
      << ReadFile(worker->log());
  EXPECT_TRUE(worker->Running());
}

// With the coordinator's certificate the status page is HTTPS (and may then listen on any
// address); plain HTTP on that port gets no page.
// Who a client is for the budgets (docs/security.md "Budgets"): the subject of a verified client
// certificate, else the peer's address. With one job per client, two clients with certificates of
// their own and one without (127.0.0.1) each get their job; a second one of the same client is
// refused, naming it.
TEST_F(TlsFarm, AClientCertificateIsTheClientOfTheBudgets) {
  MakeCertificate("alice", "ca", "2");
  MakeCertificate("bob", "ca", "2");
  CoordinatorProcess limited(dir_ / "limited", dir_.path(),
                             {"--tls-cert", Path("server.pem"), "--tls-key", Path("server.key"),
                              "--tls-client-ca", Path("ca.pem"), "--limit", "jobs_per_client=1"},
                             0, Path("client-token"));
  const auto client = [&](const std::string& name) {
    return std::make_unique<FarmClient>(
        limited.address(), "tls-client-token", 10,
        name.empty() ? CaOnly() : ResolveClientTls(Path("ca.pem"), Path(name + ".pem"), Path(name + ".key")));
  };
  auto alice = client("alice"), bob = client("bob"), anonymous = client("");
  const std::string hash = alice->UploadScene(CollectBundle(Binaries::Scene())).scene_hash();
  const photonfarm::v1::JobSpec spec = test_util::CornellPhotonMapSpec(hash, 16, 16, 1, 1);
  EXPECT_FALSE(alice->SubmitJob(spec).empty());
  try {
    alice->SubmitJob(spec);
    ADD_FAILURE() << "a second job of the same certificate was accepted";
  } catch (const RpcError& e) {
    EXPECT_EQ(e.code(), grpc::StatusCode::RESOURCE_EXHAUSTED) << e.what();
    EXPECT_NE(std::string(e.what()).find("client 'cert:"), std::string::npos) << e.what();
    EXPECT_NE(std::string(e.what()).find("CN=alice"), std::string::npos) << e.what();
  }
  EXPECT_FALSE(bob->SubmitJob(spec).empty()) << "another certificate is another client";
  EXPECT_FALSE(anonymous->SubmitJob(spec).empty()) << "no certificate: the address is the client";
  try {
    anonymous->SubmitJob(spec);
    ADD_FAILURE() << "a second job of 127.0.0.1 was accepted";
  } catch (const RpcError& e) {
    EXPECT_NE(std::string(e.what()).find("client 'ipv4:127.0.0.1'"), std::string::npos) << e.what();
  }
}

TEST_F(TlsFarm, TheStatusPageIsHttpsWithTheCoordinatorsCertificate) {
  const int port = coordinator_->http_port();
  ASSERT_GT(port, 0);
  size_t https_lines = 0;
  for (const auto& entry : fs::directory_iterator(dir_.path()))
    if (entry.path().extension() == ".out")
      https_lines +=
          Grep(entry.path(), "http on 0\\.0\\.0\\.0:" + std::to_string(port) + " \\(https\\)").size();
  EXPECT_EQ(https_lines, 1u) << "the coordinator's second line says the page is HTTPS";
  httplib::SSLClient https("127.0.0.1", port);
  https.set_ca_cert_path(Path("ca.pem"));
  https.enable_server_certificate_verification(true);
  auto r = https.Get("/api/status", {{"Authorization", "Bearer tls-client-token"}});
  ASSERT_TRUE(r) << httplib::to_string(r.error());
  EXPECT_EQ(r->status, 200);
  EXPECT_EQ(r->body, R"({"jobs":[],"workers":[]})");
  r = https.Get("/api/status");
  ASSERT_TRUE(r);
  EXPECT_EQ(r->status, 401);
  httplib::Client plain("127.0.0.1", port);
  plain.set_read_timeout(5);
  r = plain.Get("/api/status", {{"Authorization", "Bearer tls-client-token"}});
  EXPECT_FALSE(r && r->status == 200) << "plain HTTP was answered";
}

// The status page follows the gRPC port's rule: plaintext on a network address is refused unless
// --insecure, and then without a client token (the page's password).
TEST(ListenPolicy, NonLoopbackStatusPageNeedsTls) {
  TestDir dir;
  RunResult r = RunCommand(
      {Binaries::Coordinator(), "--http", "0.0.0.0:0", "--data-dir", (dir / "d1").string()}, dir.path(), 10);
  EXPECT_EQ(r.exit_code, 1) << r.err;
  EXPECT_NE(r.err.find(
                "refusing to serve the status page (--http 0.0.0.0:0) on a non-loopback address without TLS"),
            std::string::npos)
      << r.err;
  std::ofstream(dir / "t") << "some-token\n";
  r = RunCommand({Binaries::Coordinator(), "--http", "0.0.0.0:0", "--data-dir", (dir / "d2").string(),
                  "--insecure", "--client-token-file", (dir / "t").string()},
                 dir.path(), 10);
  EXPECT_EQ(r.exit_code, 1) << r.err;
  EXPECT_NE(r.err.find("would cross the network readable"), std::string::npos) << r.err;
  // Loopback stays plain HTTP.
  CoordinatorProcess loopback(dir / "d3", dir.path(), {"--http", "127.0.0.1:0"});
  EXPECT_GT(loopback.http_port(), 0);
}

// Plaintext on a network address is refused unless --insecure (and then without tokens).
TEST(ListenPolicy, NonLoopbackPlaintextNeedsInsecure) {
  TestDir dir;
  RunResult r =
      RunCommand({Binaries::Coordinator(), "--listen", "0.0.0.0:0", "--data-dir", (dir / "d1").string()},
                 dir.path(), 30);
  EXPECT_EQ(r.exit_code, 1);
  EXPECT_NE(r.err.find("without TLS"), std::string::npos) << r.err;
  std::ofstream(dir / "t") << "some-token\n";
  r = RunCommand({Binaries::Coordinator(), "--listen", "0.0.0.0:0", "--data-dir", (dir / "d2").string(),
                  "--insecure", "--client-token-file", (dir / "t").string()},
                 dir.path(), 30);
  EXPECT_EQ(r.exit_code, 1);
  EXPECT_NE(r.err.find("readable"), std::string::npos) << r.err;
}

// Tokens are parsed strictly: blank or multi-line tokens are start-up errors, never "open".
TEST(TokenPolicy, BlankOrMultiLineTokensAreStartUpErrors) {
  TestDir dir;
  std::ofstream(dir / "two-lines") << "first\nsecond\n";
  RunResult r = RunCommand({Binaries::Coordinator(), "--data-dir", (dir / "d1").string(),
                            "--client-token-file", (dir / "two-lines").string()},
                           dir.path(), 30);
  EXPECT_EQ(r.exit_code, 1);
  EXPECT_NE(r.err.find("single line"), std::string::npos) << r.err;
  r = RunCommand({Binaries::Coordinator(), "--data-dir", (dir / "d2").string()}, dir.path(), 30,
                 {{"PF_CLIENT_TOKEN", "   "}});
  EXPECT_EQ(r.exit_code, 1);
  EXPECT_NE(r.err.find("empty"), std::string::npos) << r.err;
  // A newline inside the token: pf and pf-worker stop with a usage error instead of aborting.
  r = RunCommand({Binaries::Pf(), "list", "--coordinator", "127.0.0.1:1"}, dir.path(), 30,
                 {{"PF_TOKEN", "abc\ndef"}});
  EXPECT_NE(r.exit_code, 134) << r.err;
  EXPECT_NE(r.err.find("single line"), std::string::npos) << r.err;
  r = RunCommand({Binaries::Worker(), "--coordinator", "127.0.0.1:1", "--cache-dir", (dir / "c").string()},
                 dir.path(), 30, {{"PF_TOKEN", "abc\ndef"}});
  EXPECT_EQ(r.exit_code, 2) << r.err;
  EXPECT_NE(r.err.find("single line"), std::string::npos) << r.err;
}

}  // namespace
}  // namespace pf::e2e
