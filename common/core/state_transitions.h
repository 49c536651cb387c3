#pragma once
// Checked state transitions: the legal moves between the states of one state machine, declared
// once as a table beside the states (docs/design.md, S6). A move the table does not hold is a bug
// of its owner, never something a peer can cause: std::logic_error, not a silent change (on the
// coordinator a map piece done twice would count twice towards its map, docs/farm.md "Photon maps
// traced once"; the worker's pull loop, worker/worker_state.h). Used by server/scheduling/
// (map_states.h) and worker/, hence here in core: it knows nothing of either.
//
// Not thread-safe by itself: the states it checks are guarded by their owner's lock.

#include <array>
#include <cstddef>
#include <initializer_list>
#include <stdexcept>
#include <string>
#include <utility>

namespace pf {

template <typename State, size_t kStates>
class StateTransitions {
 public:
  // `what` names the kind of work and `names[s]` state s in errors; `legal` holds the allowed
  // (from, to) pairs (a state to itself only if listed).
  StateTransitions(const char* what, std::array<const char*, kStates> names,
                   std::initializer_list<std::pair<State, State>> legal)
      : what_(what), names_(names) {
    for (const auto& [from, to] : legal) allowed_.at(size_t(from)).at(size_t(to)) = true;
  }

  bool Allows(State from, State to) const { return allowed_.at(size_t(from)).at(size_t(to)); }
  // Throws std::logic_error ("map piece: done → leased is not a legal transition") unless allowed.
  void Check(State from, State to) const {
    if (!Allows(from, to))
      throw std::logic_error(std::string(what_) + ": " + names_[size_t(from)] + " → " + names_[size_t(to)] +
                             " is not a legal transition");
  }
  // `state` becomes `to` after Check.
  void Move(State& state, State to) const {
    Check(state, to);
    state = to;
  }

 private:
  const char* what_;
  std::array<const char*, kStates> names_;
  std::array<std::array<bool, kStates>, kStates> allowed_{};
};

}  // namespace pf
