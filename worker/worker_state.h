#pragma once
// The pull loop's states and the only moves between them (docs/design.md, S6; the diagram is in
// worker.h). Worker::SetState checks every change against WorkerTransitions(): a move the table
// does not hold is a bug of the loop and throws std::logic_error (common/core/state_transitions.h)
// instead of leaving `state()` and the debug log telling a story the code did not follow.

#include <cstddef>

#include "common/core/state_transitions.h"

namespace pf::worker {

enum class State {
  kConnecting,
  kBackoff,
  kIdle,
  kFetchingScene,
  kBuildingMap,
  kRendering,
  kReporting,
  kStopping
};
inline constexpr size_t kStateCount = size_t(State::kStopping) + 1;

// "connecting", "fetching-scene", … as in the log lines.
const char* StateName(State s);

// The legal moves. Staying in a state is not a move (SetState ignores it); `stopping` is final.
const StateTransitions<State, kStateCount>& WorkerTransitions();

}  // namespace pf::worker
