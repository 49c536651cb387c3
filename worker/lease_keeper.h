#pragma once
// Keeps one task's lease alive on a thread of its own from the moment the task is leased until it
// is reported: the scene and map fetches and a piece's upload included, not only the render (a
// large map's fetch can take a good part of the lease). A heartbeat (ExtendLease, with the
// render's progress) every third of the lease's duration; when the coordinator answers that the
// lease is gone, TaskExecution::lease_lost is set and the loop abandons the task (docs/farm.md,
// "Worker"). Stop() (or the destructor) ends it.

#include <memory>
#include <string>
#include <thread>

#include "worker/coordinator_client.h"
#include "worker/task_execution.h"

namespace pf::worker {

class LeaseKeeper {
 public:
  // `client` outlives the keeper.
  LeaseKeeper(CoordinatorClient& client, std::string lease_id, std::string ctx,
              std::shared_ptr<TaskExecution> exec);
  LeaseKeeper(const LeaseKeeper&) = delete;
  LeaseKeeper& operator=(const LeaseKeeper&) = delete;
  ~LeaseKeeper() { Stop(); }

  void Stop();
  // The coordinator said the lease is gone: whatever is still to do for the task is wasted.
  bool lost() const;

 private:
  std::shared_ptr<TaskExecution> exec_;
  std::thread thread_;
};

}  // namespace pf::worker
