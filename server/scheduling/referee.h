#pragma once
// The coordinator as referee (docs/farm.md "Result verification"; referee_hook.h): it renders a
// task itself — ExecuteTask, the renderer pf-worker runs, with the scene from the scene store and
// maps it traces itself (never a map a worker traced) — and tells the scheduler the digest of its
// result (Scheduler::RefereeVerdict). On a thread of its own, one task at a time: no RPC, tick or
// scheduler lock waits for a render. Renders are rare: a mismatch (a faulty or hostile worker), or
// a verification no worker may do.

#include <atomic>
#include <cstdint>
#include <limits>
#include <memory>
#include <mutex>
#include <string>

#include "common/photon/map_cache.h"
#include "common/render/scene_runtime.h"
#include "server/executor.h"
#include "server/scheduling/referee_hook.h"

namespace pf::server {

class Scheduler;
class SceneStore;

class Referee final : public RefereeHook {
 public:
  // `threads`: of one render (the coordinator's own cores; 1 keeps it out of the RPCs' way).
  Referee(SceneStore& scenes, int threads);
  ~Referee() override;  // Stop()
  Referee(const Referee&) = delete;
  Referee& operator=(const Referee&) = delete;

  // Set once, before use.
  void SetScheduler(Scheduler* scheduler) { scheduler_ = scheduler; }
  void Judge(RefereeCase c) override;
  // Stops the render in flight (soon: ExecuteTask's cancel flag) and drops what waits; no verdict
  // is given for them (the coordinator is stopping).
  void Stop();

  struct Counters {
    uint64_t rendered = 0, failed = 0;
    double seconds = 0;  // wall time of the renders
  };
  Counters counters() const;

 private:
  void Render(const RefereeCase& c);
  std::shared_ptr<const SceneRuntime> SceneOf(const std::string& hash, const std::string& entry);

  SceneStore& scenes_;
  int threads_;
  Scheduler* scheduler_ = nullptr;
  std::atomic<bool> stopping_{false};
  mutable std::mutex mu_;
  Counters counters_;
  std::string scene_hash_;  // the scene kept loaded (the last one rendered)
  std::shared_ptr<const SceneRuntime> scene_;
  PhotonMapCache maps_{2};  // maps it traced itself: a job's next verification may use the same map
  Executor executor_{1, std::numeric_limits<size_t>::max()};
};

}  // namespace pf::server
