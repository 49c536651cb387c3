#pragma once
// The states of the coordinator's photon-map work (distributed_maps.h) and their legal
// transitions (common/core/state_transitions.h).
//
//   map:    tracing ──all pieces in──▶ building ──assembled──▶ built
//              │  ▲                       │  ▲ (a stored piece unreadable, or a conviction purges it)
//              │  └───────────────────────┘  │
//              ├──found built on disk────────┼─▶ built ──a conviction purges it──▶ tracing
//              └──a piece failed on too many workers, or assembly failed──▶ left to workers (final)
//   piece:  queued ──leased──▶ leased ──uploaded──▶ done
//              ▲                 │                   │
//              └─failed, expired,┘                   │
//                returned, refused                   │
//              ▲─────────────────────────────────────┘ (its file unreadable, or its uploader convicted)
//           queued ──found on disk──▶ done

#include "common/core/state_transitions.h"

namespace pf::server {

enum class MapState { kTracing, kBuilding, kBuilt, kLeftToWorkers };
enum class PieceState { kQueued, kLeased, kDone };

inline const StateTransitions<MapState, 4>& MapTransitions() {
  using S = MapState;
  static const StateTransitions<MapState, 4> table("photon map",
                                                   {"tracing", "building", "built", "left to workers"},
                                                   {{S::kTracing, S::kBuilding},
                                                    {S::kTracing, S::kBuilt},
                                                    {S::kTracing, S::kLeftToWorkers},
                                                    {S::kBuilding, S::kBuilt},
                                                    {S::kBuilding, S::kTracing},
                                                    {S::kBuilding, S::kLeftToWorkers},
                                                    {S::kBuilt, S::kTracing}});
  return table;
}

inline const StateTransitions<PieceState, 3>& PieceTransitions() {
  using S = PieceState;
  static const StateTransitions<PieceState, 3> table("map piece", {"queued", "leased", "done"},
                                                     {{S::kQueued, S::kLeased},
                                                      {S::kQueued, S::kDone},
                                                      {S::kLeased, S::kQueued},
                                                      {S::kLeased, S::kDone},
                                                      {S::kDone, S::kQueued}});
  return table;
}

}  // namespace pf::server
