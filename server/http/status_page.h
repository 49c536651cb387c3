#pragma once
// The coordinator's web status page (pf-coordinator --http ADDR), served with Debian's
// cpp-httplib next to the gRPC port:
//
//   GET /                      HTML: jobs (progress, noise, ETA, tasks per state), workers (id,
//                              host, current task, tasks done, photons/s) and every job's live
//                              preview; the page reloads itself every 2 s
//   GET /api/status            the same as JSON
//   GET /jobs/<id>/preview.png the job's merged image now, tone-mapped (auto exposure)
//   GET /jobs/<id>             the job's page: status, preview, events (newest first), downloads
//   GET /jobs/<id>/image.exr   the merged image now, as GetImage sends it (encoded in memory)
//   POST /jobs/<id>/<action>   cancel, pause, resume, requeue (as it was) or delete the job, as
//                              pf does (the page's buttons); JSON answer, HTTP code from the gRPC
//                              one (404 unknown job, 409 not in a state for it, ...). Cross-site
//                              requests are refused (403): the request must carry the header
//                              `X-Photonfarm-Action: <action>`, which a page of another site
//                              cannot send without a CORS preflight this server never answers,
//                              and an `Origin` header, when present, must be this server's.
//
// Credentials are the gRPC side's (server/rpc/auth.h, one check): with a token configured every
// request needs `Authorization: Bearer <token>` — or HTTP Basic with the token as the password,
// which a browser asks for — else 401. The listen address defaults to loopback; the transport
// follows the gRPC port's rule (Coordinator::Start; docs/security.md, "The web status page"):
// HTTPS with the coordinator's certificate when it has one. Sizes, deadlines and slow clients are
// handled before any of this by the gate (server/http/http_gate.h).

#include <memory>
#include <string>
#include <vector>

#include "photonfarm/v1/farm.pb.h"
#include "server/rpc/auth.h"

namespace pf::server {

class Scheduler;
class GatedHttpServer;
class CoordinatorApi;
}  // namespace pf::server
namespace httplib {
struct Request;
struct Response;
}  // namespace httplib
namespace pf::server {

// "PORT" or ":PORT" mean 127.0.0.1:PORT; else HOST:PORT. InputError if malformed.
std::pair<std::string, int> ParseHttpListen(const std::string& listen);

// The page for these jobs and workers (pure: tested without a server).
std::string RenderStatusPage(const std::vector<photonfarm::v1::JobStatus>& jobs,
                             const std::vector<photonfarm::v1::WorkerInfo>& workers);

// One job's page (GET /jobs/<id>): its status, a larger preview, downloads of the image (EXR) and
// the preview (PNG), and its events newest first (`dropped`: older ones no longer kept).
std::string RenderJobPage(const photonfarm::v1::JobStatus& status,
                          const std::vector<photonfarm::v1::TaskEvent>& events, uint64_t dropped);

class StatusHttpServer {
 public:
  // With `tls_cert_pem` (and its key): HTTPS with that certificate. InputError if it does not load.
  // `actions`: what the POST routes call (null: the page is read-only and they answer 404).
  StatusHttpServer(Scheduler& scheduler, RoleTokens tokens, const std::string& tls_cert_pem = "",
                   const std::string& tls_key_pem = "", CoordinatorApi* actions = nullptr);
  ~StatusHttpServer();  // Stop()
  StatusHttpServer(const StatusHttpServer&) = delete;
  StatusHttpServer& operator=(const StatusHttpServer&) = delete;

  // Binds (port 0: a free port) and serves on a thread; returns the port. SystemError if the
  // address cannot be bound.
  int Start(const std::string& listen);
  void Stop();
  bool tls() const;  // served over HTTPS

 private:
  // POST /jobs/<id>/<action> (see the header comment).
  void Act(const httplib::Request& req, httplib::Response& res);

  Scheduler& scheduler_;
  const RoleTokens tokens_;
  CoordinatorApi* actions_;
  std::unique_ptr<GatedHttpServer> server_;
};

}  // namespace pf::server
