#include "server/rpc/watch_hub.h"

#include <grpcpp/server_context.h>
#include <spdlog/spdlog.h>

#include <cmath>
#include <deque>
#include <optional>
#include <vector>

#include "proto/limits.h"
#include "server/rpc/job_images.h"
#include "server/rpc/status_mapping.h"

namespace pf::server {
namespace v1 = photonfarm::v1;

namespace {

constexpr double kDefaultInterval = 0.5;
constexpr double kMaxInterval = 3600;

bool IsFinal(v1::JobState s) {
  return s == v1::JOB_STATE_SUCCEEDED || s == v1::JOB_STATE_FAILED || s == v1::JOB_STATE_CANCELLED;
}

}  // namespace

class WatchSession : public std::enable_shared_from_this<WatchSession> {
 public:
  WatchSession(grpc::ServerWriteReactor<v1::JobUpdate>* reactor, grpc::CallbackServerContext* context,
               Scheduler& scheduler, Executor& executor, const Clock& clock, std::string job_id, bool images,
               double interval)
      : reactor_(reactor),
        context_(context),
        scheduler_(scheduler),
        executor_(executor),
        clock_(clock),
        job_id_(std::move(job_id)),
        images_(images),
        interval_(interval) {}

  void MarkDirty() {
    {
      std::lock_guard lock(mu_);
      dirty_ = true;
    }
    Pump();
  }
  void OnWriteDone(bool ok) {
    {
      std::lock_guard lock(mu_);
      write_in_flight_ = false;
      if (!ok && !close_status_) close_status_ = grpc::Status(grpc::StatusCode::CANCELLED, "stream closed");
    }
    Pump();
  }
  void OnCancel() { Close(grpc::Status(grpc::StatusCode::CANCELLED, "watch cancelled by the client")); }
  void Close(grpc::Status status) {
    {
      std::lock_guard lock(mu_);
      if (!close_status_) close_status_ = std::move(status);
    }
    Pump();
  }

  // A write outstanding for `unread_seconds`: the client does not read (docs/security.md
  // "Budgets"). The call is cancelled — gRPC then fails the write and the stream finishes — so
  // the session lets go of its snapshot and its place in the watcher budget. True if it did so.
  // Shutdown calls it with 0 and no `client`: a client that does not read does not hold up the
  // coordinator's stop for its grace period.
  bool EndIfUnread(double unread_seconds, const std::string& client) {
    double waited = 0;
    {
      std::lock_guard lock(mu_);
      if (finished_ || !write_in_flight_ || cancelling_ || ended_unread_) return false;
      waited = clock_.Now() - write_started_;
      if (waited < unread_seconds) return false;
      cancelling_ = true;  // no Finish (and so no OnDone, which frees the context) until TryCancel returned
      ended_unread_ = true;
      if (!close_status_)
        close_status_ = grpc::Status(grpc::StatusCode::CANCELLED, "watch ended: the client did not read");
    }
    if (!client.empty())
      spdlog::warn("WatchJob of job {} by {}: an update unread for {:.1f} s; the stream is ended", job_id_,
                   limits::Quote(client, 200), waited);
    context_->TryCancel();
    {
      std::lock_guard lock(mu_);
      cancelling_ = false;
    }
    Pump();
    return true;
  }

  // Decides the next step under the lock and performs it outside.
  void Pump() {
    enum class Action { kNone, kWrite, kFinish, kBuild } action = Action::kNone;
    grpc::Status finish_status;
    {
      std::lock_guard lock(mu_);
      if (finished_ || write_in_flight_ || building_ || cancelling_) return;
      if (close_status_) {
        finished_ = true;
        finish_status = *close_status_;
        action = Action::kFinish;
      } else if (!queue_.empty()) {
        current_ = std::move(queue_.front());
        queue_.pop_front();
        write_in_flight_ = true;
        write_started_ = clock_.Now();
        action = Action::kWrite;
      } else if (final_queued_) {
        finished_ = true;
        finish_status = grpc::Status::OK;
        action = Action::kFinish;
      } else if (dirty_ && clock_.Now() >= next_allowed_) {
        dirty_ = false;
        building_ = true;
        next_allowed_ = clock_.Now() + interval_;
        action = Action::kBuild;
      }
    }
    switch (action) {
      case Action::kNone:
        return;
      case Action::kWrite:
        reactor_->StartWrite(&current_);
        return;
      case Action::kFinish:
        reactor_->Finish(finish_status);
        return;
      case Action::kBuild:
        if (!images_) {
          Build();
          return;
        }
        if (!executor_.Post([self = shared_from_this()] { self->Build(); })) {
          std::lock_guard lock(mu_);
          building_ = false;
          dirty_ = true;  // retried on the next tick
        }
        return;
    }
  }

 private:
  void Build() {
    std::vector<v1::JobUpdate> updates;
    bool final_state = false;
    const grpc::Status status = Guarded("WatchJob", [&] {
      if (images_) {
        EncodedImage img = EncodeJobImage(scheduler_, job_id_);
        final_state = IsFinal(img.status.state());
        for (v1::ImageChunk& chunk : img.chunks) {
          v1::JobUpdate u;
          *u.mutable_status() = img.status;
          *u.mutable_image() = std::move(chunk);
          updates.push_back(std::move(u));
        }
      } else {
        v1::JobUpdate u;
        *u.mutable_status() = scheduler_.Status(job_id_);
        final_state = IsFinal(u.status().state());
        updates.push_back(std::move(u));
      }
      return grpc::Status::OK;
    });
    {
      std::lock_guard lock(mu_);
      building_ = false;
      if (!status.ok() && !close_status_) close_status_ = status;
      for (v1::JobUpdate& u : updates) queue_.push_back(std::move(u));
      if (final_state) final_queued_ = true;
    }
    Pump();
  }

  grpc::ServerWriteReactor<v1::JobUpdate>* const reactor_;
  grpc::CallbackServerContext* const context_;  // valid until OnDone, i.e. while !finished_
  Scheduler& scheduler_;
  Executor& executor_;
  const Clock& clock_;
  const std::string job_id_;
  const bool images_;
  const double interval_;

  std::mutex mu_;
  bool dirty_ = true;  // the first update goes out at once
  bool write_in_flight_ = false;
  double write_started_ = 0;   // Clock::Now() of the outstanding write's StartWrite
  bool cancelling_ = false;    // EndIfUnread is cancelling the call
  bool ended_unread_ = false;  // … or has done so
  bool building_ = false;
  bool final_queued_ = false;
  bool finished_ = false;
  std::optional<grpc::Status> close_status_;
  double next_allowed_ = -1e300;
  std::deque<v1::JobUpdate> queue_;
  v1::JobUpdate current_;
};

namespace {

class WatchReactor final : public grpc::ServerWriteReactor<v1::JobUpdate> {
 public:
  std::shared_ptr<WatchSession> session;
  void OnWriteDone(bool ok) override { session->OnWriteDone(ok); }
  void OnCancel() override { session->OnCancel(); }
  void OnDone() override { delete this; }
};

class FinishedReactor final : public grpc::ServerWriteReactor<v1::JobUpdate> {
 public:
  explicit FinishedReactor(const grpc::Status& status) { Finish(status); }
  void OnDone() override { delete this; }
};

}  // namespace

WatchHub::WatchHub(Scheduler& scheduler, Executor& executor, const Clock& clock, const Budgets& budgets)
    : scheduler_(scheduler),
      executor_(executor),
      clock_(clock),
      per_client_(budgets.watchers_per_client),
      total_(budgets.watchers_total),
      unread_seconds_(budgets.watch_unread_seconds) {}

grpc::ServerWriteReactor<v1::JobUpdate>* WatchHub::Open(grpc::CallbackServerContext* context,
                                                        const std::string& client,
                                                        const v1::WatchJobRequest& request,
                                                        const grpc::Status& precheck) {
  if (!precheck.ok()) return new FinishedReactor(precheck);
  double interval = request.min_interval_seconds();
  std::string job_id;  // the whole id of a prefix (JobRegistry::Resolve)
  const grpc::Status status = Guarded("WatchJob", [&] {
    if (!std::isfinite(interval) || interval < 0 || interval > kMaxInterval)
      return grpc::Status(grpc::StatusCode::INVALID_ARGUMENT,
                          "min_interval_seconds: must be a finite number in [0, 3600]");
    if (request.job_id().empty()) return grpc::Status(grpc::StatusCode::INVALID_ARGUMENT, "job_id: required");
    try {
      limits::CheckId(request.job_id(), "job_id");
    } catch (const InputError& e) {
      return grpc::Status(grpc::StatusCode::INVALID_ARGUMENT, e.what());
    }
    job_id = scheduler_.Status(request.job_id()).job_id();  // NOT_FOUND for an unknown job
    return grpc::Status::OK;
  });
  if (!status.ok()) return new FinishedReactor(status);
  if (interval == 0) interval = kDefaultInterval;

  auto* reactor = new WatchReactor();
  reactor->session = std::make_shared<WatchSession>(reactor, context, scheduler_, executor_, clock_, job_id,
                                                    request.include_images(), interval);
  std::shared_ptr<WatchSession> session = reactor->session;
  bool closed;
  grpc::Status over_budget;
  {
    std::lock_guard lock(mu_);
    closed = shutdown_;
    if (!closed) {
      // Forget sessions that ended, so the map does not grow with every watcher ever seen; count
      // the others (at most watchers_total).
      uint64_t mine = 0;
      for (auto it = sessions_.begin(); it != sessions_.end();) {
        if (it->second.session.expired()) {
          it = sessions_.erase(it);
        } else {
          mine += it->second.client == client;
          ++it;
        }
      }
      if (mine >= per_client_)
        over_budget = grpc::Status(
            grpc::StatusCode::RESOURCE_EXHAUSTED,
            "WatchJob: client " + limits::Quote(client, 200) + " has " + std::to_string(mine) +
                " open watches, the budget watchers_per_client = " + std::to_string(per_client_) +
                " (pf-coordinator --limit watchers_per_client=N); end one first");
      else if (sessions_.size() >= total_)
        over_budget =
            grpc::Status(grpc::StatusCode::RESOURCE_EXHAUSTED,
                         "WatchJob: " + std::to_string(sessions_.size()) +
                             " watches are open, the budget watchers_total = " + std::to_string(total_) +
                             " (pf-coordinator --limit watchers_total=N); retry later");
      else
        sessions_.emplace(job_id, Entry{client, session});
    }
  }
  if (!over_budget.ok()) {
    // The session never started: it finishes its reactor at once, before any snapshot.
    spdlog::info("WatchJob: {}", over_budget.error_message());
    session->Close(over_budget);
    return reactor;
  }
  if (closed)
    session->Close(grpc::Status(grpc::StatusCode::UNAVAILABLE, "coordinator shutting down"));
  else
    session->Pump();
  return reactor;
}

void WatchHub::Notify(const std::string& job_id) {
  std::vector<std::shared_ptr<WatchSession>> live;
  {
    std::lock_guard lock(mu_);
    auto [begin, end] = sessions_.equal_range(job_id);
    for (auto it = begin; it != end;) {
      if (auto s = it->second.session.lock()) {
        live.push_back(std::move(s));
        ++it;
      } else {
        it = sessions_.erase(it);
      }
    }
  }
  for (auto& s : live) s->MarkDirty();
}

void WatchHub::Tick() {
  std::vector<std::pair<std::shared_ptr<WatchSession>, std::string>> live;
  {
    std::lock_guard lock(mu_);
    for (auto it = sessions_.begin(); it != sessions_.end();) {
      if (auto s = it->second.session.lock()) {
        live.emplace_back(std::move(s), it->second.client);
        ++it;
      } else {
        it = sessions_.erase(it);
      }
    }
  }
  for (auto& [s, client] : live)
    if (!s->EndIfUnread(unread_seconds_, client)) s->Pump();
}

void WatchHub::Shutdown() {
  std::vector<std::shared_ptr<WatchSession>> live;
  {
    std::lock_guard lock(mu_);
    shutdown_ = true;
    for (auto& [id, entry] : sessions_)
      if (auto s = entry.session.lock()) live.push_back(std::move(s));
    sessions_.clear();
  }
  for (auto& s : live) {
    s->Close(grpc::Status(grpc::StatusCode::UNAVAILABLE, "coordinator shutting down"));
    s->EndIfUnread(0, "");
  }
}

size_t WatchHub::sessions() {
  std::lock_guard lock(mu_);
  size_t n = 0;
  for (auto& [id, entry] : sessions_) n += !entry.session.expired();
  return n;
}

}  // namespace pf::server
