// server/scheduling/map_states.h and common/core/state_transitions.h: the states of map pieces and maps move
// only along their tables; any other move is a logic error, and the state is left as it was.
#include <gtest/gtest.h>

#include <stdexcept>
#include <string>

#include "server/scheduling/map_states.h"

namespace pf::server {
namespace {

TEST(MapStates, APieceMovesOnlyAlongItsTable) {
  const auto& t = PieceTransitions();
  PieceState s = PieceState::kQueued;
  t.Move(s, PieceState::kLeased);
  t.Move(s, PieceState::kQueued);  // failed, expired, returned or refused
  t.Move(s, PieceState::kLeased);
  t.Move(s, PieceState::kDone);
  EXPECT_EQ(s, PieceState::kDone);
  // Done twice would count twice towards the map; leased again would hand it out twice.
  EXPECT_THROW(t.Move(s, PieceState::kDone), std::logic_error);
  EXPECT_THROW(t.Move(s, PieceState::kLeased), std::logic_error);
  EXPECT_EQ(s, PieceState::kDone) << "an illegal move changes nothing";
  t.Move(s, PieceState::kQueued);  // its uploader convicted, or its file unreadable
  EXPECT_FALSE(t.Allows(PieceState::kQueued, PieceState::kQueued));
  EXPECT_TRUE(t.Allows(PieceState::kQueued, PieceState::kDone)) << "found on disk";
}

TEST(MapStates, AMapLeftToTheWorkersStaysThere) {
  const auto& t = MapTransitions();
  for (MapState to : {MapState::kTracing, MapState::kBuilding, MapState::kBuilt, MapState::kLeftToWorkers})
    EXPECT_FALSE(t.Allows(MapState::kLeftToWorkers, to));
  EXPECT_FALSE(t.Allows(MapState::kBuilt, MapState::kBuilding)) << "a built map is traced again first";
  EXPECT_FALSE(t.Allows(MapState::kTracing, MapState::kTracing));
  MapState s = MapState::kTracing;
  t.Move(s, MapState::kBuilding);
  t.Move(s, MapState::kBuilt);
  t.Move(s, MapState::kTracing);  // purged by a conviction
  try {
    MapState left = MapState::kLeftToWorkers;
    t.Move(left, MapState::kBuilt);
    ADD_FAILURE() << "no error";
  } catch (const std::logic_error& e) {
    EXPECT_EQ(std::string(e.what()), "photon map: left to workers → built is not a legal transition");
  }
}

}  // namespace
}  // namespace pf::server
