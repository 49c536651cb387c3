// pf-coordinator: the photonfarm coordinator (server/coordinator.h; docs/farm.md, "Coordinator").
//
//   pf-coordinator --data-dir DIR [--listen 127.0.0.1:0] [--config FILE]
//                  [--client-token-file FILE] [--worker-token-file FILE]
//                  [--tls-cert PEM --tls-key PEM [--tls-client-ca PEM]] [--insecure]
//                  [--lease-seconds 30] [--max-attempts 3] [--checkpoint-ms 0] [--log-level info]
//                  [--allow-mixed-versions] [--limit NAME=VALUE ...]
//                  [--verify-fraction 0.03] [--no-verify-outliers] [--verify-piece-fraction 0.1]
//                  [--referee-threads 1] [--retain-finished 7d] [--maps-quota 2G] [--data-quota 50G]
//
// Prints one line on stdout once it serves — "listening on HOST:PORT" (the bound port, also for
// :0; with --http a second line, "http on HOST:PORT", for the web status page, with " (https)" when it
// uses the coordinator's certificate) — and logs to stderr, one line
// per event with job and task ids (leases and merges too: use --log-level warn for very many tiny tasks).
// SIGTERM / SIGINT shut down gracefully (exit 0). Exit 2 on a usage error, 1 on a start-up error.
#include <signal.h>
#include <spdlog/sinks/stdout_color_sinks.h>
#include <spdlog/spdlog.h>
#include <CLI/CLI.hpp>

#include <algorithm>
#include <cctype>
#include <csignal>
#include <cstdio>
#include <cstdlib>
#include <fstream>
#include <iostream>
#include <sstream>
#include <thread>

#include "common/core/byte_size_text.h"
#include "common/core/duration_text.h"
#include "common/core/error.h"
#include "photonfarm_version.h"
#include "rpc/grpc_channel.h"
#include "server/coordinator.h"
#include "server/http/status_page.h"

namespace {

std::string ReadPem(const std::string& file, const char* flag) {
  if (file.empty()) return "";
  std::ifstream in(file, std::ios::binary);
  if (!in) throw pf::InputError(std::string(flag) + ": cannot read '" + file + "'");
  std::stringstream ss;
  ss << in.rdbuf();
  return ss.str();
}

std::string HostOf(const std::string& listen) {
  const size_t colon = listen.rfind(':');
  return colon == std::string::npos ? listen : listen.substr(0, colon);
}

}  // namespace

int main(int argc, char** argv) {
  pf::server::CoordinatorOptions options;
  std::string client_token_file, worker_token_file, tls_cert, tls_key, tls_client_ca, log_level = "info";
  int checkpoint_ms = 0;
  std::vector<std::string> limits;
  CLI::App app{"pf-coordinator: the photonfarm coordinator (jobs, scheduling, merging, persistence)"};
  app.add_option("--listen", options.listen, "Address to serve on; port 0 picks a free port")
      ->capture_default_str();
  app.add_option("--data-dir", options.data_dir, "Directory for the database, checkpoints and scenes")
      ->capture_default_str();
  app.add_option(
      "--client-token-file", client_token_file,
      "File holding the bearer token clients (pf, RenderService) must send (else env PF_CLIENT_TOKEN; "
      "none: RenderService open)");
  app.add_option("--worker-token-file", worker_token_file,
                 "File holding the bearer token workers (WorkerService) must send (else env PF_WORKER_TOKEN; "
                 "none: WorkerService open). A worker token cannot call RenderService and vice versa");
  app.add_option("--tls-cert", tls_cert, "PEM certificate chain: serve TLS (with --tls-key)");
  app.add_option("--tls-key", tls_key, "PEM private key of --tls-cert");
  app.add_option("--tls-client-ca", tls_client_ca,
                 "PEM CA: workers must present a client certificate it signed (mTLS)");
  app.add_flag("--insecure", options.insecure,
               "Allow plaintext without authentication on a non-loopback address (trusted networks only)");
  app.add_option("--lease-seconds", options.lease_seconds, "Lease length; workers extend it by heartbeat")
      ->capture_default_str()
      ->check(CLI::Range(0.1, 86400.0));
  app.add_option("--max-attempts", options.max_attempts,
                 "Distinct workers a task may fail on before its job fails (docs/farm.md, Worker health)")
      ->capture_default_str()
      ->check(CLI::Range(1, 1000));
  app.add_option(
         "--blocklist-after", options.blocklist_failures,
         "Failed attempts in one job after which a worker gets no more of that job's work (0 = never)")
      ->capture_default_str()
      ->check(CLI::Range(0, 1000));
  app.add_option(
         "--quarantine-after", options.quarantine_jobs,
         "Jobs blocklisting a worker within --quarantine-seconds after which it gets no leases at all "
         "for --quarantine-seconds (0 = never)")
      ->capture_default_str()
      ->check(CLI::Range(0, 1000));
  app.add_option("--quarantine-seconds", options.quarantine_seconds,
                 "The window of --quarantine-after, and how long a quarantine lasts")
      ->capture_default_str()
      ->check(CLI::Range(0.0, 30.0 * 86400));
  std::string retain_finished;
  app.add_option("--retain-finished", retain_finished,
                 "Delete succeeded, failed and cancelled jobs this long after they finished (7d, 12h, 30m or "
                 "seconds), as pf purge --older-than does; default: keep them (docs/farm.md, Deleting jobs)")
      ->check(pf::DurationTextProblem);
  app.add_option("--checkpoint-ms", checkpoint_ms,
                 "0: journal every result and acknowledge it only once stored (docs/farm.md, Durability); N: "
                 "no journal, acknowledge at once, checkpoint at most every N ms (a crash re-runs up to N ms "
                 "of work)")
      ->capture_default_str()
      ->check(CLI::Range(0, 3600000));
  app.add_option(
      "--http", options.http_listen,
      "Serve the web status page (jobs, workers, live previews) on [HOST:]PORT; HOST defaults to "
      "127.0.0.1, port 0 picks a free port; same token as gRPC (Bearer, or Basic with the token as "
      "password); HTTPS with --tls-cert/--tls-key, and without them a non-loopback HOST is refused as "
      "for --listen");
  app.add_option("--map-build-threads", options.map_build_threads,
                 "Threads that assemble and balance one distributed photon map (0 = all cores)")
      ->capture_default_str()
      ->check(CLI::Range(0, 1024));
  app.add_option("--map-chunk-photons", options.map_chunk_photons,
                 "Photons per traced piece of a distributed map (rounded up to a multiple of 4096)")
      ->capture_default_str()
      ->check(CLI::Range(uint64_t(4096), uint64_t(1) << 28));
  std::string maps_quota;
  app.add_option("--maps-quota", maps_quota,
                 "Most bytes the stored photon maps (DATA-DIR/maps) may hold (500M, 2G): past it the least "
                 "recently used maps no queued, running or paused job uses are deleted; default: no limit "
                 "(docs/farm.md, The map store's quota)")
      ->check(pf::ByteSizeTextProblem);
  std::string data_quota;
  app.add_option("--data-quota", data_quota,
                 "Most bytes DATA-DIR may hold (50G): past it the finished jobs that ended first are "
                 "deleted as pf delete does; queued, running and paused jobs never; default: no limit "
                 "(docs/farm.md, The data dir's quota)")
      ->check(pf::ByteSizeTextProblem);
  app.add_flag("--allow-mixed-versions", options.allow_mixed_versions,
               "Lease to workers of another build too. By default a worker whose `pf-worker --version` "
               "differs from this coordinator's (" PF_VERSION
               ") is refused and exits with code 4: two builds may trace other photons or estimate "
               "differently, and one job's image would mix them. Also resumes, at start-up, jobs submitted "
               "under another build instead of re-running them");
  app.add_option("--verify-fraction", options.verify_fraction,
                 "Fraction of merged results another worker renders again, compared bit for bit; on a "
                 "mismatch the coordinator renders the task and convicts the worker that differs "
                 "(docs/farm.md, Result verification). 0 = none at random")
      ->capture_default_str()
      ->check(CLI::Range(0.0, 1.0));
  app.add_flag(
      "!--no-verify-outliers", options.verify_outliers,
      "Do not verify the results whose mean is an outlier among the job's results of the same pixels");
  app.add_option("--verify-piece-fraction", options.verify_piece_fraction,
                 "Fraction of uploaded photon-map pieces the coordinator traces again in full (the first "
                 "4096 photons of every piece always are); a piece that differs convicts its uploader")
      ->capture_default_str()
      ->check(CLI::Range(0.0, 1.0));
  app.add_option(
         "--referee-threads", options.referee_threads,
         "Threads of the coordinator's own renders of a task (a mismatch, or a verification no worker "
         "may do)")
      ->capture_default_str()
      ->check(CLI::Range(1, 1024));
  app.add_option(
      "--limit", limits,
      "A per-client or global budget, NAME=VALUE, repeatable (docs/security.md \"Budgets\"): "
      "jobs_per_client, jobs_total, tasks_per_job, tasks_total, pixels_per_job, pixels_total, "
      "watchers_per_client, watchers_total, watch_unread_seconds, upload_bytes, uploads_per_client, "
      "uploads_total, scene_bytes_total; over one, a request is refused RESOURCE_EXHAUSTED");
  app.add_option("--log-level", log_level, "trace, debug, info, warn, error")
      ->capture_default_str()
      ->check(CLI::IsMember({"trace", "debug", "info", "warn", "warning", "error", "critical", "off"}));
  // A deployment's settings in one file (deploy/README.md): every option above by its long name,
  // TOML `key = value` (a repeatable one as an array); the command line wins over the file. A key
  // the coordinator does not know is a usage error, not ignored.
  app.set_config("--config", "",
                 "TOML file of these options by long name (key = value); the command line wins");
  app.allow_config_extras(CLI::config_extras_mode::error);
  app.set_version_flag("--version", "pf-coordinator " PF_VERSION);
  try {
    app.parse(argc, argv);
  } catch (const CLI::ParseError& e) {
    return app.exit(e) == 0 ? 0
                            : 2;  // --help/--version: 0; usage errors: 2 (CLI11's own codes are 105, 109...)
  }
  options.checkpoint_interval_seconds = checkpoint_ms / 1000.0;
  if (!retain_finished.empty())
    options.retain_finished_seconds = pf::ParseDurationText(retain_finished, "--retain-finished");
  if (!maps_quota.empty()) options.maps_quota_bytes = pf::ParseByteSizeText(maps_quota, "--maps-quota");
  if (!data_quota.empty()) options.data_quota_bytes = pf::ParseByteSizeText(data_quota, "--data-quota");

  auto logger = spdlog::stderr_color_mt("pf-coordinator");
  spdlog::set_default_logger(logger);
  spdlog::set_pattern("[%Y-%m-%d %H:%M:%S.%e] [%^%l%$] %v");
  spdlog::set_level(spdlog::level::from_str(log_level));

  // SIGINT/SIGTERM are handled by one thread with sigwait; every other thread (gRPC's included,
  // created later) inherits the blocked mask. A shell starts background jobs with SIGINT ignored,
  // and an ignored signal is discarded even while blocked: restore the default disposition first.
  std::signal(SIGINT, SIG_DFL);
  std::signal(SIGTERM, SIG_DFL);
  sigset_t signals;
  sigemptyset(&signals);
  sigaddset(&signals, SIGINT);
  sigaddset(&signals, SIGTERM);
  pthread_sigmask(SIG_BLOCK, &signals, nullptr);
  // A write to a peer that has reset (OpenSSL's socket BIOs of the status page send without
  // MSG_NOSIGNAL; a closed stderr pipe) must fail with EPIPE, not end the coordinator: its default
  // action would kill it before any authentication (docs/security.md "The web status page").
  std::signal(SIGPIPE, SIG_IGN);

  try {
    options.client_token = pf::ResolveToken(client_token_file, "PF_CLIENT_TOKEN", nullptr);
    options.worker_token = pf::ResolveToken(worker_token_file, "PF_WORKER_TOKEN", nullptr);
    if (!options.client_token.empty() && options.client_token == options.worker_token)
      throw pf::InputError("the client and worker tokens are the same: roles need different credentials");
    options.tls_cert_pem = ReadPem(tls_cert, "--tls-cert");
    options.tls_key_pem = ReadPem(tls_key, "--tls-key");
    options.tls_client_ca_pem = ReadPem(tls_client_ca, "--tls-client-ca");
    for (const std::string& limit : limits) pf::server::SetBudget(&options.budgets, limit);
    pf::server::Coordinator coordinator(options);
    const int port = coordinator.Start();
    std::printf("listening on %s:%d\n", HostOf(options.listen).c_str(), port);
    if (coordinator.http_port() > 0)
      std::printf("http on %s:%d%s\n", pf::server::ParseHttpListen(options.http_listen).first.c_str(),
                  coordinator.http_port(), coordinator.http_tls() ? " (https)" : "");
    std::fflush(stdout);

    std::thread signal_thread([&] {
      int sig = 0;
      sigwait(&signals, &sig);
      if (sig != 0) spdlog::info("signal {}: shutting down", sig == SIGINT ? "SIGINT" : "SIGTERM");
      coordinator.Shutdown();
    });
    coordinator.Wait();  // returns once the signal thread's Shutdown has completed
    signal_thread.join();
    // Exit 1 when the final flush could not store everything (a full disk): the tasks whose results
    // were not stored run again at the next start, but an operator must see that it happened.
    return coordinator.StoredEverything() ? 0 : 1;
  } catch (const std::exception& e) {
    spdlog::critical("{}", e.what());
    return 1;
  }
}
