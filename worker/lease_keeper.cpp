#include "worker/lease_keeper.h"

#include <spdlog/spdlog.h>

#include <algorithm>

namespace pf::worker {
namespace {

// The heartbeat thread: ends when the keeper stops, the render is done or the lease is gone.
void Heartbeat(CoordinatorClient& client, const std::string& lease_id, const std::string& ctx,
               TaskExecution& exec) {
  double lease_seconds = exec.lease_seconds;
  while (true) {
    const auto interval = Seconds(std::max(0.05, lease_seconds / 3.0));
    {
      std::unique_lock lock(exec.mutex);
      if (exec.cv.wait_for(lock, interval, [&] { return exec.stop_heartbeat || exec.done; })) return;
    }
    const double progress = std::min(1.0, double(exec.progress.load()) / double(exec.pixels));
    const CoordinatorClient::Extension e = client.ExtendLease(lease_id, progress, interval);
    switch (e.answer) {
      case CoordinatorClient::Extension::Answer::kGone: {
        std::lock_guard lock(exec.mutex);
        exec.lease_lost = true;
        exec.cv.notify_all();
        return;
      }
      case CoordinatorClient::Extension::Answer::kExtended:
        if (e.lease_seconds > 0) lease_seconds = e.lease_seconds;
        spdlog::trace("extended {} progress={:.2f}", ctx, progress);
        break;
      case CoordinatorClient::Extension::Answer::kUnanswered:
        spdlog::warn("ExtendLease {}: {}", ctx, StatusToString(e.status));
        break;
    }
  }
}

}  // namespace

LeaseKeeper::LeaseKeeper(CoordinatorClient& client, std::string lease_id, std::string ctx,
                         std::shared_ptr<TaskExecution> exec)
    : exec_(exec), thread_([&client, lease_id = std::move(lease_id), ctx = std::move(ctx), exec] {
        Heartbeat(client, lease_id, ctx, *exec);
      }) {}

bool LeaseKeeper::lost() const {
  std::lock_guard lock(exec_->mutex);
  return exec_->lease_lost;
}

void LeaseKeeper::Stop() {
  {
    std::lock_guard lock(exec_->mutex);
    exec_->stop_heartbeat = true;
    exec_->cv.notify_all();
  }
  if (thread_.joinable()) thread_.join();
}

}  // namespace pf::worker
