// pf-worker's command line and process life (worker_main.h): options, logging, signals, exit
// codes. See worker/worker.h for the state machine and docs/farm.md (## Worker) for the
// operator's view.
//
// Signals: SIGTERM or SIGINT = finish the current task within --grace (else hand its lease
// back), then exit 0; a second signal hands the lease back at once.
// Exit codes: 0 stopped by a signal (or --max-tasks reached), 2 usage error, 1 start-up failure,
// 4 the coordinator refused this worker's build (another `--version`; docs/farm.md, "Upgrades").
#include "worker/worker_main.h"

#include <pthread.h>
#include <signal.h>
#include <spdlog/sinks/stdout_color_sinks.h>
#include <spdlog/spdlog.h>
#include <unistd.h>
#include <CLI/CLI.hpp>

#include <cstdio>
#include <thread>

#include "common/core/error.h"
#include "photonfarm_version.h"
#include "rpc/address.h"
#include "rpc/grpc_channel.h"
#include "worker/worker.h"

namespace {

std::string DefaultWorkerId() {
  char host[256] = {0};
  if (gethostname(host, sizeof(host) - 1) != 0) std::snprintf(host, sizeof(host), "worker");
  return std::string(host) + "-" + std::to_string(getpid());
}

}  // namespace

namespace pf::worker {

int RunWorkerProcess(int argc, char** argv, std::shared_ptr<WorkerFaults> faults) {
  pf::worker::WorkerOptions o;
  o.faults = std::move(faults);
  std::string token_file, tls_ca, tls_cert, tls_key, log_level = "info";
  std::string cache_dir, map_cache_dir;
  uint64_t map_cache_mb = 4096;
  int threads = 0;
  CLI::App app{
      "pf-worker — photonfarm render worker: leases tasks from a pf-coordinator (long poll), renders\n"
      "their pixel subsets with its own photon maps, reports the pixel sums.\n\n"
      "  pf-worker --coordinator 127.0.0.1:7000 --cache-dir /var/cache/pf-worker\n\n"
      "SIGTERM/SIGINT: finish the current task within --grace or hand it back, then exit 0.\n"
      "Exit codes: 0 stopped, 1 start-up failure, 2 usage error, 4 the coordinator runs another\n"
      "build (`--version`) and refuses this one: farms run one build (docs/farm.md, Upgrades)."};
  app.add_option("--coordinator", o.coordinator, "Coordinator address HOST:PORT")
      ->required()
      ->check(CLI::Validator([](std::string& v) { return pf::CoordinatorAddressProblem(v); }, "HOST:PORT"));
  app.add_option(
      "--token-file", token_file,
      "File holding the worker's bearer token, one line (default: $PF_TOKEN_FILE, else $PF_TOKEN)");
  app.add_option("--tls-ca", tls_ca,
                 "PEM roots of the coordinator's TLS certificate: connect with TLS (default: $PF_TLS_CA)");
  app.add_option("--tls-cert", tls_cert,
                 "PEM client certificate for mTLS (with --tls-key; default: $PF_TLS_CERT)");
  app.add_option("--tls-key", tls_key, "PEM private key of --tls-cert (default: $PF_TLS_KEY)");
  app.add_option("--worker-id", o.worker_id, "Name in the coordinator's logs (default: HOST-PID)");
  app.add_option("--threads", threads, "Render threads (0 = all cores)")
      ->capture_default_str()
      ->check(CLI::Range(0, 1024));
  app.add_option("--cache-dir", cache_dir, "Scene bundle cache (default: $TMPDIR/pf-worker-cache)");
  app.add_option("--map-cache", o.map_cache_capacity, "Photon maps kept in memory (LRU)")
      ->capture_default_str();
  app.add_option("--scene-cache", o.scene_cache_capacity, "Loaded scenes kept in memory (LRU)")
      ->capture_default_str();
  app.add_option("--poll-seconds", o.poll_seconds, "LeaseTask long-poll wait")
      ->capture_default_str()
      ->check(CLI::Range(0.05, 30.0));
  app.add_option("--rpc-timeout", o.rpc_timeout_seconds, "Deadline of short RPCs, seconds")
      ->capture_default_str()
      ->check(CLI::Range(0.1, 600.0));
  app.add_option("--grace", o.grace_seconds,
                 "SIGTERM: seconds to finish the current task before handing it back")
      ->capture_default_str()
      ->check(CLI::Range(0.0, 86400.0));
  app.add_option("--max-backoff", o.max_backoff_seconds, "Cap of the reconnect backoff, seconds")
      ->capture_default_str()
      ->check(CLI::Range(0.1, 300.0));
  app.add_option("--report-retry", o.report_retry_seconds,
                 "Keep a finished result this long while the coordinator is unreachable, seconds")
      ->capture_default_str()
      ->check(CLI::Range(0.0, 86400.0));
  app.add_option("--max-tasks", o.max_tasks, "Exit 0 after this many tasks (0 = run until signalled)")
      ->capture_default_str();
  app.add_option(
      "--map-cache-dir", map_cache_dir,
      "Built photon maps fetched from the coordinator, by content address (default: CACHE-DIR/maps)");
  app.add_option("--map-cache-mb", map_cache_mb,
                 "Size limit of --map-cache-dir in MiB; least recently used maps go first (0 = keep none)")
      ->capture_default_str()
      ->check(CLI::Range(uint64_t(0), uint64_t(1) << 30));
  app.add_option("--log-level", log_level, "trace|debug|info|warn|error|off")
      ->capture_default_str()
      ->check(CLI::IsMember({"trace", "debug", "info", "warn", "warning", "error", "critical", "off"}));
  app.set_version_flag("--version", "pf-worker " PF_VERSION);
  try {
    app.parse(argc, argv);
  } catch (const CLI::ParseError& e) {
    return app.exit(e) == 0 ? 0 : 2;
  }
  // Logs go to stderr: stdout carries results (`pf submit` prints only the job id).
  spdlog::set_default_logger(spdlog::stderr_color_mt("pf-worker"));
  spdlog::set_level(spdlog::level::from_str(log_level));
  spdlog::set_pattern("%Y-%m-%dT%H:%M:%S.%e %^%l%$ [pf-worker] %v");
  spdlog::flush_on(spdlog::level::trace);  // logs are the worker's event record (tests read them)

  // Signals go to a dedicated thread (sigwait), never to a handler: block them before any
  // other thread exists so that every thread inherits the mask.
  sigset_t signals;
  sigemptyset(&signals);
  sigaddset(&signals, SIGTERM);
  sigaddset(&signals, SIGINT);
  pthread_sigmask(SIG_BLOCK, &signals, nullptr);
  signal(SIGPIPE, SIG_IGN);

  try {
    o.token = pf::ResolveToken(token_file);
    o.tls = pf::ResolveClientTls(tls_ca, tls_cert, tls_key);
    o.threads = threads > 0 ? threads : int(std::max(1u, std::thread::hardware_concurrency()));
    if (o.worker_id.empty()) o.worker_id = DefaultWorkerId();
    const char* tmp = std::getenv("TMPDIR");
    o.cache_dir = cache_dir.empty() ? std::filesystem::path(tmp ? tmp : "/tmp") / "pf-worker-cache"
                                    : std::filesystem::path(cache_dir);
    o.map_cache_dir = map_cache_dir;
    o.map_cache_bytes = map_cache_mb << 20;
    pf::worker::Worker worker(o);
    std::thread([&worker, signals] {
      int count = 0;
      while (true) {
        int sig = 0;
        if (sigwait(&signals, &sig) != 0) continue;
        spdlog::info("received {}", sig == SIGTERM ? "SIGTERM" : "SIGINT");
        if (count++ == 0)
          worker.RequestStop();
        else
          worker.RequestAbort();
      }
    }).detach();
    const int code = worker.Run();
    spdlog::shutdown();
    std::fflush(nullptr);
    // A render thread may still be busy with a task whose lease was handed back: do not wait.
    std::_Exit(code);
  } catch (const pf::InputError& e) {
    spdlog::error("{}", e.what());
    return 2;
  } catch (const std::exception& e) {
    spdlog::error("{}", e.what());
    return 1;
  }
}

}  // namespace pf::worker
