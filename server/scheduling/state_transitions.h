#pragma once
// Moved to common/core/state_transitions.h (the worker's pull loop checks its moves with it too);
// this forwarding header keeps code written against the old path building. New code includes
// common/core/state_transitions.h.

#include "common/core/state_transitions.h"

namespace pf::server {
using pf::StateTransitions;
}  // namespace pf::server
