#include "server/rpc/budgets.h"

#include <grpc/grpc_security_constants.h>
#include <grpcpp/security/auth_context.h>
#include <grpcpp/server_context.h>

#include <cmath>
#include <string>
#include <utility>

#include "common/core/error.h"
#include "common/scene/scene_bundle.h"
#include "proto/convert.h"
#include "proto/limits.h"
#include "server/peer_host.h"
#include "server/scheduling/scheduler.h"
#include "server/store/scene_store.h"

namespace pf::server {

namespace {

struct Entry {
  const char* name;
  uint64_t Budgets::*value;  // null for watch_unread_seconds
  uint64_t hard_max;         // 0: none
};

constexpr Entry kEntries[] = {
    {"jobs_per_client", &Budgets::jobs_per_client, 0},
    {"jobs_total", &Budgets::jobs_total, 0},
    {"tasks_per_job", &Budgets::tasks_per_job, limits::kMaxTasksPerJob},
    {"tasks_total", &Budgets::tasks_total, 0},
    {"pixels_per_job", &Budgets::pixels_per_job, kMaxImagePixels},
    {"pixels_total", &Budgets::pixels_total, 0},
    {"watchers_per_client", &Budgets::watchers_per_client, 0},
    {"watchers_total", &Budgets::watchers_total, 0},
    {"watch_unread_seconds", nullptr, 0},
    {"upload_bytes", &Budgets::upload_bytes, kMaxBundleBytes},
    {"uploads_per_client", &Budgets::uploads_per_client, 0},
    {"uploads_total", &Budgets::uploads_total, 0},
    {"scene_bytes_total", &Budgets::scene_bytes_total, 0},
};

// "budget NAME = VALUE (pf-coordinator --limit NAME=N)": how every refusal names its budget.
std::string Named(const char* name, uint64_t value) {
  return "the budget " + std::string(name) + " = " + std::to_string(value) + " (pf-coordinator --limit " +
         name + "=N)";
}

std::string Client(const std::string& client) {
  return "client " + limits::Quote(client, 200);
}

}  // namespace

void SetBudget(Budgets* budgets, std::string_view assignment) {
  const size_t eq = assignment.find('=');
  const std::string name(assignment.substr(0, eq));
  const std::string value = eq == std::string_view::npos ? "" : std::string(assignment.substr(eq + 1));
  const Entry* entry = nullptr;
  for (const Entry& e : kEntries)
    if (name == e.name) entry = &e;
  if (eq == std::string_view::npos || entry == nullptr) {
    std::string names;
    for (const Entry& e : kEntries) names += std::string(names.empty() ? "" : ", ") + e.name;
    throw InputError("--limit " + limits::Quote(assignment) + ": expected NAME=VALUE with NAME one of " +
                     names);
  }
  if (entry->value == nullptr) {
    size_t used = 0;
    double seconds = 0;
    try {
      seconds = std::stod(value, &used);
    } catch (const std::exception&) {
      used = 0;
    }
    if (used == 0 || used != value.size() || !std::isfinite(seconds) || seconds <= 0 || seconds > 86400)
      throw InputError("--limit " + name + ": " + limits::Quote(value) +
                       " is not a number of seconds in (0, 86400]");
    budgets->watch_unread_seconds = seconds;
    return;
  }
  uint64_t number = 0;
  bool ok = !value.empty() && value.size() <= 19;
  for (const char c : value) {
    ok = ok && c >= '0' && c <= '9';
    if (ok) number = number * 10 + uint64_t(c - '0');
  }
  if (!ok || number == 0)
    throw InputError("--limit " + name + ": " + limits::Quote(value) + " is not a whole number >= 1");
  if (entry->hard_max != 0 && number > entry->hard_max)
    throw InputError("--limit " + name + ": " + value + " is above the hard limit " +
                     std::to_string(entry->hard_max) + " (proto/limits.h)");
  budgets->*(entry->value) = number;
}

std::string DescribeBudgets(const Budgets& budgets) {
  std::string out;
  for (const Entry& e : kEntries) {
    if (!out.empty()) out += ' ';
    out += e.name;
    out += '=';
    if (e.value) {
      out += std::to_string(budgets.*(e.value));
    } else {
      char seconds[32];
      std::snprintf(seconds, sizeof seconds, "%g", budgets.watch_unread_seconds);
      out += seconds;
    }
  }
  return out;
}

std::string ClientOf(const grpc::CallbackServerContext& context) {
  if (const std::shared_ptr<const grpc::AuthContext> auth = context.auth_context()) {
    const std::vector<grpc::string_ref> subject = auth->FindPropertyValues(GRPC_X509_SUBJECT_PROPERTY_NAME);
    if (!subject.empty()) return "cert:" + std::string(subject.front().data(), subject.front().size());
  }
  const std::string peer = context.peer();
  const std::string host = PeerHost(peer);
  if (peer.starts_with("ipv4:")) return "ipv4:" + host;
  if (peer.starts_with("ipv6:")) return "ipv6:[" + host + "]";
  return peer;
}

Reservation& Reservation::operator=(Reservation&& other) noexcept {
  if (this != &other) {
    Release();
    admission_ = std::exchange(other.admission_, nullptr);
    upload_ = other.upload_;
    client_ = std::move(other.client_);
    amount_a_ = other.amount_a_;
    amount_b_ = other.amount_b_;
  }
  return *this;
}

void Reservation::Release() {
  if (Admission* a = std::exchange(admission_, nullptr)) a->Release(*this);
}

Reservation Admission::AdmitJob(const std::string& client, uint64_t tasks, uint64_t pixels) {
  const Budgets& b = budgets_;
  if (tasks > b.tasks_per_job)
    throw LimitError("spec.plan: " + std::to_string(tasks) + " tasks exceed " +
                     Named("tasks_per_job", b.tasks_per_job) + "; use larger tiles or fewer maps/rounds");
  if (pixels > b.pixels_per_job)
    throw LimitError("spec.camera.width/height: " + std::to_string(pixels) + " pixels exceed " +
                     Named("pixels_per_job", b.pixels_per_job));
  std::lock_guard lock(mu_);
  const ActiveLoad load = scheduler_.Load(client);
  auto pending = pending_client_jobs_.find(client);
  const uint64_t client_jobs =
      load.client_jobs + (pending == pending_client_jobs_.end() ? 0 : pending->second);
  if (client_jobs + 1 > b.jobs_per_client)
    throw LimitError("spec: " + Client(client) + " has " + std::to_string(client_jobs) +
                     " queued or running jobs, " + Named("jobs_per_client", b.jobs_per_client) +
                     "; wait for some to finish or cancel them");
  if (load.jobs + pending_jobs_ + 1 > b.jobs_total)
    throw LimitError("spec: " + std::to_string(load.jobs + pending_jobs_) + " jobs are queued or running, " +
                     Named("jobs_total", b.jobs_total) + "; retry later");
  if (load.tasks + pending_tasks_ + tasks > b.tasks_total)
    throw LimitError("spec.plan: " + std::to_string(tasks) + " tasks more than the " +
                     std::to_string(load.tasks + pending_tasks_) + " held for other jobs exceed " +
                     Named("tasks_total", b.tasks_total) + "; retry later");
  if (load.pixels + pending_pixels_ + pixels > b.pixels_total)
    throw LimitError("spec.camera.width/height: " + std::to_string(pixels) + " pixels more than the " +
                     std::to_string(load.pixels + pending_pixels_) + " held for other jobs exceed " +
                     Named("pixels_total", b.pixels_total) + "; retry later");
  ++pending_jobs_;
  pending_tasks_ += tasks;
  pending_pixels_ += pixels;
  ++pending_client_jobs_[client];
  return Reservation(this, /*upload=*/false, client, tasks, pixels);
}

Reservation Admission::AdmitUpload(const std::string& client, uint64_t bytes) {
  const Budgets& b = budgets_;
  if (bytes > b.upload_bytes)
    throw LimitError("bundle.files: " + std::to_string(bytes) + " bytes exceed " +
                     Named("upload_bytes", b.upload_bytes));
  std::lock_guard lock(mu_);
  auto it = client_uploads_.find(client);
  const uint64_t mine = it == client_uploads_.end() ? 0 : it->second;
  if (mine + 1 > b.uploads_per_client)
    throw LimitError("bundle: " + Client(client) + " has " + std::to_string(mine) + " uploads in flight, " +
                     Named("uploads_per_client", b.uploads_per_client) + "; retry when one has finished");
  if (uploads_ + 1 > b.uploads_total)
    throw LimitError("bundle: " + std::to_string(uploads_) + " uploads are in flight, " +
                     Named("uploads_total", b.uploads_total) + "; retry later");
  ++uploads_;
  upload_bytes_ += bytes;
  ++client_uploads_[client];
  return Reservation(this, /*upload=*/true, client, bytes, 0);
}

void Admission::CheckSceneBytes(const Reservation& upload, const std::function<bool()>& already_stored) {
  const uint64_t stored = scenes_.StoredBytes();
  uint64_t in_flight = 0;
  {
    std::lock_guard lock(mu_);
    in_flight = upload_bytes_;  // this upload's bytes included
  }
  if (stored + in_flight <= budgets_.scene_bytes_total || already_stored()) return;
  throw LimitError("bundle.files: " + std::to_string(upload.amount_a_) + " bytes more than the " +
                   std::to_string(stored) + " bytes of stored scenes (and " +
                   std::to_string(in_flight - upload.amount_a_) + " of other uploads in flight) exceed " +
                   Named("scene_bytes_total", budgets_.scene_bytes_total));
}

void Admission::Release(const Reservation& r) {
  std::lock_guard lock(mu_);
  auto& per_client = r.upload_ ? client_uploads_ : pending_client_jobs_;
  if (auto it = per_client.find(r.client_); it != per_client.end() && --it->second == 0) per_client.erase(it);
  if (r.upload_) {
    --uploads_;
    upload_bytes_ -= r.amount_a_;
  } else {
    --pending_jobs_;
    pending_tasks_ -= r.amount_a_;
    pending_pixels_ -= r.amount_b_;
  }
}

}  // namespace pf::server
