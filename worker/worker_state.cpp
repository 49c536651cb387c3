#include "worker/worker_state.h"

#include <array>

namespace pf::worker {
namespace {

constexpr std::array<const char*, kStateCount> kNames = {
    "connecting", "backoff", "idle", "fetching-scene", "building-map", "rendering", "reporting", "stopping"};

}  // namespace

const char* StateName(State s) {
  return size_t(s) < kNames.size() ? kNames[size_t(s)] : "?";
}

const StateTransitions<State, kStateCount>& WorkerTransitions() {
  using S = State;
  // Every state but `stopping` may end in `stopping` (a stop request, --max-tasks, a refused
  // build). After a task, whatever its end, the loop reconnects (`connecting`) before the next
  // poll, or backs off first if the coordinator was unreachable.
  static const StateTransitions<State, kStateCount> table(
      "worker", kNames,
      {
          // The channel is ready (poll), or not yet.
          {S::kConnecting, S::kIdle},
          {S::kConnecting, S::kBackoff},
          {S::kConnecting, S::kStopping},
          // After the sleep: reconnect, or try CompleteTask again.
          {S::kBackoff, S::kConnecting},
          {S::kBackoff, S::kReporting},
          {S::kBackoff, S::kStopping},
          // The long poll: a task, no task now (poll again), a failed call; a task that cannot be
          // read is failed from here.
          {S::kIdle, S::kFetchingScene},
          {S::kIdle, S::kConnecting},
          {S::kIdle, S::kBackoff},
          {S::kIdle, S::kStopping},
          // The scene is here: obtain the map, or render (the map is in memory, or none is used);
          // or the task ended (failed, lease gone) or the coordinator is unreachable.
          {S::kFetchingScene, S::kBuildingMap},
          {S::kFetchingScene, S::kRendering},
          {S::kFetchingScene, S::kConnecting},
          {S::kFetchingScene, S::kBackoff},
          {S::kFetchingScene, S::kStopping},
          // The map is built (rendering), or the render or map piece ended before a pixel was
          // counted (reporting); or the task ended, or FetchMap found the coordinator unreachable.
          {S::kBuildingMap, S::kRendering},
          {S::kBuildingMap, S::kReporting},
          {S::kBuildingMap, S::kConnecting},
          {S::kBuildingMap, S::kBackoff},
          {S::kBuildingMap, S::kStopping},
          // A result to report, or none (failed, abandoned, handed back).
          {S::kRendering, S::kReporting},
          {S::kRendering, S::kConnecting},
          {S::kRendering, S::kStopping},
          // Reported (or rejected), or the coordinator is away: back off and retry or give up.
          {S::kReporting, S::kConnecting},
          {S::kReporting, S::kBackoff},
          {S::kReporting, S::kStopping},
      });
  return table;
}

}  // namespace pf::worker
