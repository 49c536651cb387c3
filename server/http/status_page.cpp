#include "server/http/status_page.h"

#include <fmt/format.h>
#include <httplib.h>
#include <spdlog/spdlog.h>

#include <ctime>
#include <nlohmann/json.hpp>

#include "common/core/error.h"
#include "common/image/png_io.h"
#include "proto/convert.h"
#include "rpc/grpc_channel.h"
#include "server/errors.h"
#include "server/http/http_gate.h"
#include "server/rpc/auth.h"
#include "server/rpc/coordinator_api.h"
#include "server/rpc/job_images.h"
#include "server/rpc/status_mapping.h"
#include "server/scheduling/scheduler.h"

namespace pf::server {
namespace v1 = photonfarm::v1;

namespace {

std::string Escape(const std::string& text) {
  std::string out;
  for (char c : text) {
    switch (c) {
      case '&':
        out += "&amp;";
        break;
      case '<':
        out += "&lt;";
        break;
      case '>':
        out += "&gt;";
        break;
      case '"':
        out += "&quot;";
        break;
      case '\'':
        out += "&#39;";
        break;
      default:
        out += c;
    }
  }
  return out;
}

// The HTTP answer to a refused action, from its gRPC code (server/rpc/status_mapping.h).
int HttpStatusOf(grpc::StatusCode code) {
  switch (code) {
    case grpc::StatusCode::INVALID_ARGUMENT:
      return 400;
    case grpc::StatusCode::NOT_FOUND:
      return 404;
    case grpc::StatusCode::FAILED_PRECONDITION:
      return 409;
    case grpc::StatusCode::RESOURCE_EXHAUSTED:
      return 429;
    case grpc::StatusCode::UNAVAILABLE:
      return 503;
    default:
      return 500;
  }
}

// A job's buttons: pause or resume and cancel while it is live, requeue and delete once it ended.
std::string ActionButtons(const v1::JobStatus& s) {
  const auto button = [&](const char* action) {
    return fmt::format("<button onclick=\"act('{0}', '{1}')\">{1}</button>", Escape(s.job_id()), action);
  };
  if (s.state() == v1::JOB_STATE_QUEUED || s.state() == v1::JOB_STATE_RUNNING)
    return button(s.paused() ? "resume" : "pause") + " " + button("cancel");
  return button("requeue") + " " + button("delete");
}

// A GET about one job: `answer(job_id)` fills the response; an unknown job is 404, another
// error 500 (logged with `what`).
template <typename F>
void AnswerForJob(httplib::Response& res, const std::string& job_id, const char* what, F&& answer) {
  res.set_header("Cache-Control", "no-store");
  try {
    answer(job_id);
  } catch (const NotFoundError& e) {
    res.status = 404;
    res.set_content(std::string(e.what()) + "\n", "text/plain");
  } catch (const std::exception& e) {
    spdlog::warn("http: {} of job {}: {}", what, job_id, e.what());
    res.status = 500;
    res.set_content(std::string(e.what()) + "\n", "text/plain");
  }
}

std::string Duration(double s) {
  if (s < 0) return "?";
  if (s < 60) return fmt::format("{:.1f} s", s);
  if (s < 3600) return fmt::format("{} min {} s", int(s / 60), int(s) % 60);
  return fmt::format("{} h {} min", int(s / 3600), (int(s) % 3600) / 60);
}

std::string Base64Decode(std::string_view in) {
  static constexpr std::string_view kAlphabet =
      "ABCDEFGHIJKLMNOPQRSTUVWXYZabcdefghijklmnopqrstuvwxyz0123456789+/";
  std::string out;
  uint32_t bits = 0;
  int n = 0;
  for (char c : in) {
    if (c == '=') break;
    const size_t v = kAlphabet.find(c);
    if (v == std::string_view::npos) return "";
    bits = (bits << 6) | uint32_t(v);
    n += 6;
    if (n >= 8) {
      n -= 8;
      out += char((bits >> n) & 0xff);
    }
  }
  return out;
}

nlohmann::json JobJson(const v1::JobStatus& s) {
  // An animation's frames (docs/farm.md "Animation"): each frame's merged and scheduled tasks.
  nlohmann::json frames = nlohmann::json::array();
  for (const v1::FrameProgress& f : s.frames())
    frames.push_back({{"frame", f.frame()}, {"done", f.tasks_done()}, {"total", f.tasks_total()}});
  return {{"job_id", s.job_id()},
          {"frames", frames},
          {"name", s.spec().name()},
          {"state", pf::JobStateName(s.state())},
          {"paused", s.paused()},  // pf pause (docs/farm.md "Pausing a job")
          {"waiting_for", std::vector<std::string>(s.waiting_for().begin(), s.waiting_for().end())},
          {"failure_reason", s.failure_reason()},
          {"tasks",
           {{"total", s.tasks_total()},
            {"done", s.tasks_done()},
            {"running", s.tasks_running()},
            {"queued", s.tasks_queued()},
            {"cancelled", s.tasks_cancelled()}}},
          {"progress", s.progress()},
          {"elapsed_seconds", s.elapsed_seconds()},
          {"eta_seconds", s.eta_seconds()},
          {"estimated_noise_rms", s.estimated_noise_rms()},
          {"estimated_bias_rms", s.estimated_bias_rms()},
          {"estimated_error_rms", s.estimated_error_rms()},
          {"target_missed", s.target_missed()},
          {"samples_merged", s.samples_merged()},
          {"width", s.spec().camera().width()},
          {"height", s.spec().camera().height()}};
}

nlohmann::json WorkerJson(const v1::WorkerInfo& w) {
  return {{"worker_id", w.worker_id()},
          {"host", w.peer()},
          {"threads", w.threads()},
          {"version", w.version()},
          {"refused", w.refused()},
          {"refused_reason", w.refused_reason()},
          {"refused_calls", w.refused_calls()},
          {"lost", w.lost()},
          {"offline", w.offline()},
          {"quarantined", w.quarantined()},
          {"busy", w.busy()},
          {"current_job_id", w.current_job_id()},
          {"current_task_id", w.current_task_id()},
          {"tasks_done", w.tasks_done()},
          {"tasks_failed", w.tasks_failed()},
          {"photons_per_second", w.photons_per_second()},
          {"seconds_since_seen", w.seconds_since_seen()}};
}

}  // namespace

std::pair<std::string, int> ParseHttpListen(const std::string& listen) {
  std::string host = "127.0.0.1", port = listen;
  const size_t colon = listen.rfind(':');
  if (colon != std::string::npos) {
    if (colon > 0) host = listen.substr(0, colon);
    port = listen.substr(colon + 1);
  }
  if (host.size() > 2 && host.front() == '[' && host.back() == ']') host = host.substr(1, host.size() - 2);
  if (port.empty() || port.size() > 5 || port.find_first_not_of("0123456789") != std::string::npos ||
      std::stoi(port) > 65535)
    throw InputError("--http: expected PORT or HOST:PORT (port 0..65535), got '" + listen + "'");
  return {host, std::stoi(port)};
}

std::string RenderStatusPage(const std::vector<v1::JobStatus>& jobs,
                             const std::vector<v1::WorkerInfo>& workers) {
  std::string html = R"(<!DOCTYPE html>
<html lang="en"><head><meta charset="utf-8"><noscript><meta http-equiv="refresh" content="2"></noscript>
<title>photonfarm</title>
<style>
body { font: 14px/1.4 sans-serif; margin: 8px; background: #fafafa; color: #222; }
.previews { display: flex; flex-wrap: wrap; gap: 8px; margin: 0 0 12px 0; }
.previews figure { margin: 0; width: 192px; }
.previews img { width: 192px; height: 192px; object-fit: contain; background: #000; display: block;
                image-rendering: pixelated; }
.previews figcaption { font-size: 12px; }
table { border-collapse: collapse; margin-bottom: 16px; }
th, td { border: 1px solid #ccc; padding: 2px 8px; text-align: left; }
.bar { width: 120px; height: 10px; background: #ddd; display: inline-block; }
.bar span { height: 10px; background: #3a7; display: block; }
</style></head><body>
)";
  html += "<div class=\"previews\" id=\"previews\">\n";
  for (const v1::JobStatus& s : jobs)
    html += fmt::format(
        "<figure><img id=\"preview-{0}\" alt=\"preview of {0}\" src=\"/jobs/{0}/preview.png?samples={1}\">"
        "<figcaption>{0} {2}</figcaption></figure>\n",
        Escape(s.job_id()), s.samples_merged(), Escape(pf::JobStateName(s.state())));
  html += "</div>\n<div id=\"jobs-section\"><h2>Jobs</h2>\n";
  if (jobs.empty())
    html += "<p>No jobs.</p>\n";
  else {
    html +=
        "<table "
        "id=\"jobs\"><tr><th>job</th><th>name</th><th>state</th><th>progress</th><th>done</th><th>running</"
        "th>"
        "<th>queued</th><th>cancelled</th><th>elapsed</th><th>ETA</th><th>noise</th><th>actions</th></tr>\n";
    for (const v1::JobStatus& s : jobs) {
      const double frac = s.progress();
      html += fmt::format(
          "<tr><td><a href=\"/jobs/{0}\">{0}</a></td><td>{1}</td><td>{2}{3}</td><td><span "
          "class=\"bar\"><span "
          "style=\"width:{4:.0f}%\"></span></span> "
          "{5:.1f}%</td><td>{6}/{7}</td><td>{8}</td><td>{9}</td><td>{10}</td><td>{11}</td><td>{12}</"
          "td><td>{13}</"
          "td><td>{14}</td></"
          "tr>\n",
          Escape(s.job_id()), Escape(s.spec().name()),
          s.paused()                 ? "paused"
          : s.waiting_for_size() > 0 ? "waiting"
                                     : pf::JobStateName(s.state()),
          s.failure_reason().empty() ? "" : ": " + Escape(s.failure_reason()), 100 * frac, 100 * frac,
          s.tasks_done(), s.tasks_total(), s.tasks_running(), s.tasks_queued(), s.tasks_cancelled(),
          Duration(s.elapsed_seconds()),
          s.state() == v1::JOB_STATE_RUNNING || s.state() == v1::JOB_STATE_QUEUED ? Duration(s.eta_seconds())
                                                                                  : "-",
          s.estimated_noise_rms() >= 0 ? fmt::format("{:.4g}", s.estimated_noise_rms()) : "-",
          ActionButtons(s));
    }
    html += "</table>\n";
  }
  html += "</div>\n<div id=\"workers-section\"><h2>Workers</h2>\n";
  if (workers.empty())
    html += "<p>No worker has contacted this coordinator.</p>\n";
  else {
    html +=
        "<table id=\"workers\"><tr><th>worker</th><th>host</th><th>threads</th><th>current "
        "task</th><th>tasks "
        "done</th><th>failed</th><th>photons/s</th><th>last seen</th><th>build</th></tr>\n";
    for (const v1::WorkerInfo& w : workers)
      html += fmt::format(
          "<tr><td>{}</td><td>{}</td><td>{}</td><td>{}</td><td>{}</td><td>{}</td><td>{:.4g}</td><td>{} "
          "ago</td><td>{}</td></tr>\n",
          Escape(w.worker_id()), w.peer().empty() ? std::string("-") : Escape(w.peer()), w.threads(),
          // Worker health (docs/farm.md), as pf workers says it.
          w.refused()       ? "refused: " + Escape(w.refused_reason())
          : w.quarantined() ? "quarantined: " + Escape(w.quarantine_reason())
          : w.offline()     ? std::string("offline")
          : w.lost()        ? std::string("lost")
          : w.busy()        ? Escape(w.current_job_id()) + " task " + std::to_string(w.current_task_id())
                            : "idle",
          w.tasks_done(), w.tasks_failed(), w.photons_per_second(), Duration(w.seconds_since_seen()),
          Escape(w.version()));
    html += "</table>\n";
  }
  html += "</div>\n";
  // The buttons' requests (POST /jobs/<id>/<action>, with the header that proves they come from
  // this page); the answer of a refused one is shown as it is.
  // Updates in place every 2 s (without JavaScript: the <noscript> reload): the page is fetched
  // again and its two tables swapped in; a preview image is replaced only when its job merged
  // more samples (its URL names the count), so unchanged images are not fetched again and the
  // page neither flickers nor loses its scroll position.
  html += R"(<script>
async function update() {
  const r = await fetch(location.pathname, {credentials: 'same-origin', cache: 'no-store'});
  if (!r.ok) return;
  const next = new DOMParser().parseFromString(await r.text(), 'text/html');
  for (const id of ['jobs-section', 'workers-section'])
    document.getElementById(id).replaceWith(document.adoptNode(next.getElementById(id)));
  const shown = document.getElementById('previews'), fresh = next.getElementById('previews');
  const keep = new Map([...shown.children].map(f => [f.querySelector('img').getAttribute('src'), f]));
  shown.replaceChildren(...[...fresh.children].map(f => {
    const old = keep.get(f.querySelector('img').getAttribute('src'));
    if (!old) return document.adoptNode(f);
    old.querySelector('figcaption').replaceWith(document.adoptNode(f.querySelector('figcaption')));
    return old;
  }));
}
function tick() { update().catch(() => {}).finally(() => setTimeout(tick, 2000)); }
setTimeout(tick, 2000);
async function act(id, action) {
  if ((action === 'cancel' || action === 'delete') && !confirm(action + ' job ' + id + '?')) return;
  const r = await fetch('/jobs/' + encodeURIComponent(id) + '/' + action,
                        {method: 'POST', headers: {'X-Photonfarm-Action': action}, credentials: 'same-origin'});
  if (!r.ok) alert(action + ' ' + id + ': ' + (await r.text()));
  await update();
}
</script>
)";
  html += "</body></html>\n";
  return html;
}

std::string RenderJobPage(const v1::JobStatus& s, const std::vector<v1::TaskEvent>& events,
                          uint64_t dropped) {
  const std::string id = Escape(s.job_id());
  std::string html = fmt::format(
      R"(<!DOCTYPE html>
<html lang="en"><head><meta charset="utf-8"><title>{0}</title>
<style>
body {{ font: 14px/1.4 sans-serif; margin: 8px; background: #fafafa; color: #222; }}
table {{ border-collapse: collapse; margin-bottom: 16px; }}
th, td {{ border: 1px solid #ccc; padding: 2px 8px; text-align: left; }}
img {{ max-width: 512px; max-height: 512px; background: #000; image-rendering: pixelated; }}
</style></head><body>
<p><a href="/">all jobs</a></p>
<h2 id="job">{0} {1}</h2>
<p>{2}{3}, {4}/{5} tasks, {6} samples merged, elapsed {7}{8}</p>
<p><img id="preview" alt="preview of {0}" src="/jobs/{0}/preview.png?samples={6}"></p>
<p><a id="exr" href="/jobs/{0}/image.exr" download>the image now (EXR)</a> · <a id="png" href="/jobs/{0}/preview.png" download="{0}.png">preview (PNG)</a></p>
)",
      id, Escape(s.spec().name()), pf::JobStateName(s.state()),
      s.failure_reason().empty() ? "" : ": " + Escape(s.failure_reason()), s.tasks_done(), s.tasks_total(),
      s.samples_merged(), Duration(s.elapsed_seconds()),
      s.estimated_noise_rms() >= 0 ? fmt::format(", estimated noise {:.4g}", s.estimated_noise_rms()) : "");
  if (s.frames_size() > 0) {
    // The preview shows the frames stacked top to bottom, as the job's image holds them.
    html += "<h3>Frames</h3>\n<table id=\"frames\"><tr><th>frame</th><th>tasks merged</th></tr>\n";
    for (const v1::FrameProgress& f : s.frames())
      html += fmt::format("<tr><td>{}</td><td>{}/{}</td></tr>\n", f.frame(), f.tasks_done(), f.tasks_total());
    html += "</table>\n";
  }
  html += "<h3>Events</h3>\n";
  if (dropped > 0) html += fmt::format("<p>({} older events not kept)</p>\n", dropped);
  html +=
      "<table id=\"events\"><tr><th>time (UTC)</th><th>event</th><th>task</th><th>attempt</th><th>worker</th>"
      "<th>detail</th></tr>\n";
  // Newest first, as a person reads a log of what just happened.
  for (auto e = events.rbegin(); e != events.rend(); ++e) {
    const std::time_t t = std::time_t(e->unix_ms() / 1000);
    std::tm tm{};
    gmtime_r(&t, &tm);
    char when[32];
    std::strftime(when, sizeof(when), "%Y-%m-%d %H:%M:%S", &tm);
    html +=
        fmt::format("<tr><td>{}.{:03d}</td><td>{}</td><td>{}</td><td>{}</td><td>{}</td><td>{}</td></tr>\n",
                    when, int(e->unix_ms() % 1000), Escape(e->kind()), e->task_id(), e->attempt(),
                    Escape(e->worker_id()), Escape(e->detail()));
  }
  html += "</table>\n</body></html>\n";
  return html;
}

StatusHttpServer::StatusHttpServer(Scheduler& scheduler, RoleTokens tokens, const std::string& tls_cert_pem,
                                   const std::string& tls_key_pem, CoordinatorApi* actions)
    : scheduler_(scheduler),
      tokens_(std::move(tokens)),
      actions_(actions),
      server_(std::make_unique<GatedHttpServer>(HttpLimits{}, tls_cert_pem, tls_key_pem)) {
  httplib::Server& svr = *server_;
  svr.set_pre_routing_handler([this](const httplib::Request& req, httplib::Response& res) {
    std::string header;  // "" = none
    if (req.has_header("Authorization")) {
      header = req.get_header_value("Authorization");
      // Basic (what a browser sends after asking): the password is the token.
      if (header.rfind("Basic ", 0) == 0) {
        const std::string decoded = Base64Decode(std::string_view(header).substr(6));
        const size_t colon = decoded.find(':');
        header = "Bearer " + (colon == std::string::npos ? decoded : decoded.substr(colon + 1));
      }
    }
    // The page shows what RenderService shows: the client credential, by the same decision.
    const grpc::Status status = Authorize(tokens_, kWebStatusMethod, header);
    if (status.ok()) return httplib::Server::HandlerResponse::Unhandled;
    res.status = 401;
    res.set_header("WWW-Authenticate", "Basic realm=\"photonfarm\"");
    res.set_content(status.error_message() + "\n", "text/plain");
    return httplib::Server::HandlerResponse::Handled;
  });
  svr.Get("/", [this](const httplib::Request&, httplib::Response& res) {
    res.set_header("Cache-Control", "no-store");
    res.set_content(RenderStatusPage(scheduler_.List(true), scheduler_.activity().Workers()),
                    "text/html; charset=utf-8");
  });
  svr.Get("/api/status", [this](const httplib::Request&, httplib::Response& res) {
    nlohmann::json j = {{"jobs", nlohmann::json::array()}, {"workers", nlohmann::json::array()}};
    for (const v1::JobStatus& s : scheduler_.List(true)) j["jobs"].push_back(JobJson(s));
    for (const v1::WorkerInfo& w : scheduler_.activity().Workers()) j["workers"].push_back(WorkerJson(w));
    res.set_header("Cache-Control", "no-store");
    res.set_content(j.dump(), "application/json");
  });
  svr.Get(
      R"(/jobs/([A-Za-z0-9._-]+)/preview\.png)", [this](const httplib::Request& req, httplib::Response& res) {
        AnswerForJob(res, req.matches[1], "preview", [&](const std::string& job_id) {
          const ResolvedImage image = ResolveJobImage(scheduler_, job_id, nullptr);
          res.set_content(EncodePngPreview(image.image, PreviewOptions{.auto_exposure = true}), "image/png");
        });
      });
  svr.Get(R"(/jobs/([A-Za-z0-9._-]+))", [this](const httplib::Request& req, httplib::Response& res) {
    AnswerForJob(res, req.matches[1], "page", [&](const std::string& job_id) {
      const v1::JobStatus status = scheduler_.Status(job_id);
      uint64_t dropped = 0;
      const std::vector<v1::TaskEvent> events = scheduler_.activity().Events(status.job_id(), &dropped);
      res.set_content(RenderJobPage(status, events, dropped), "text/html; charset=utf-8");
    });
  });
  svr.Get(R"(/jobs/([A-Za-z0-9._-]+)/image\.exr)",
          [this](const httplib::Request& req, httplib::Response& res) {
            AnswerForJob(res, req.matches[1], "image", [&](const std::string& job_id) {
              // The merged image now, as GetImage sends it (its header says what it is of).
              std::string exr;
              for (const v1::ImageChunk& chunk : EncodeJobImage(scheduler_, job_id).chunks)
                exr += chunk.exr_bytes();
              res.set_header("Content-Disposition", "attachment; filename=\"" + job_id + ".exr\"");
              res.set_content(std::move(exr), "image/x-exr");
            });
          });
  svr.Post(R"(/jobs/([A-Za-z0-9._-]+)/(cancel|pause|resume|requeue|delete))",
           [this](const httplib::Request& req, httplib::Response& res) { Act(req, res); });
}

void StatusHttpServer::Act(const httplib::Request& req, httplib::Response& res) {
  const std::string job_id = req.matches[1];
  const std::string action = req.matches[2];
  res.set_header("Cache-Control", "no-store");
  const auto refuse = [&](int code, const std::string& why) {
    res.status = code;
    res.set_content(nlohmann::json{{"error", why}}.dump(), "application/json");
  };
  if (actions_ == nullptr) return refuse(404, "this status page is read-only");
  // Cross-site request forgery: a browser sends the page's credentials (Basic) with any request
  // to this origin, but a page of another origin cannot add this header without a CORS
  // preflight, which this server never grants.
  if (req.get_header_value("X-Photonfarm-Action") != action)
    return refuse(403,
                  "the header X-Photonfarm-Action: " + action + " is required (the page's buttons send it)");
  if (req.has_header("Origin")) {
    const std::string own = std::string(tls() ? "https://" : "http://") + req.get_header_value("Host");
    if (req.get_header_value("Origin") != own)
      return refuse(403, "Origin " + req.get_header_value("Origin") + " is not this page's (" + own + ")");
  }
  const std::string client = "web:" + req.remote_addr;
  nlohmann::json out;
  const grpc::Status status = Guarded("web " + action, [&] {
    if (action == "cancel") {
      out = JobJson(actions_->CancelJob(job_id));
    } else if (action == "pause" || action == "resume") {
      out = JobJson(actions_->SetJobPaused(job_id, action == "pause"));
    } else if (action == "delete") {
      const v1::DeleteJobResponse d = actions_->DeleteJob(job_id);
      out = {{"job_id", d.job_id()}, {"bytes_freed", d.bytes_freed()}, {"maps_removed", d.maps_removed()}};
    } else {  // requeue: as it was (pf requeue without options)
      v1::RequeueJobRequest request;
      request.set_job_id(job_id);
      const v1::RequeueJobResponse r = actions_->RequeueJob(actions_->AdmitRequeue(request, client));
      out = {{"job_id", r.job_id()}, {"requeued_from", job_id}, {"tasks_carried", r.tasks_carried()}};
    }
    return grpc::Status::OK;
  });
  spdlog::info("http: {} job {} from {}: {}", action, job_id, client,
               status.ok()
                   ? "done"
                   : std::string(StatusCodeName(status.error_code())) + ": " + status.error_message());
  if (!status.ok()) return refuse(HttpStatusOf(status.error_code()), status.error_message());
  res.set_content(out.dump(), "application/json");
}

StatusHttpServer::~StatusHttpServer() {
  Stop();
}

int StatusHttpServer::Start(const std::string& listen) {
  const auto [host, port] = ParseHttpListen(listen);
  const int bound = server_->Start(host, port);
  if (bound < 0)
    throw SystemError("--http " + listen + ": cannot bind (in use, or not an address of this machine)");
  const bool v6 = host.find(':') != std::string::npos;
  spdlog::info("http: status page on {}://{}{}{}:{}/", server_->tls() ? "https" : "http", v6 ? "[" : "", host,
               v6 ? "]" : "", bound);
  return bound;
}

bool StatusHttpServer::tls() const {
  return server_->tls();
}

void StatusHttpServer::Stop() {
  server_->Stop();
}

}  // namespace pf::server
