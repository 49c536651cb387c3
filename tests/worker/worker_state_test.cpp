// worker/worker_state.h: the pull loop's transition table holds exactly the moves of the diagram in
// worker/worker.h — each accepted, every other pair refused with std::logic_error naming both
// states — and `stopping` is final.
#include "worker/worker_state.h"

#include <gtest/gtest.h>

#include <set>
#include <sstream>
#include <stdexcept>
#include <string>
#include <utility>

namespace pf::worker {
namespace {

using S = State;

// The moves the loop makes (worker.cpp), written out here independently of the table, by name:
// each state, then the states it may move to.
const char* const kDiagram[] = {
    "connecting     -> idle backoff stopping",
    "backoff        -> connecting reporting stopping",
    "idle           -> fetching-scene connecting backoff stopping",
    "fetching-scene -> building-map rendering connecting backoff stopping",
    "building-map   -> rendering reporting connecting backoff stopping",
    "rendering      -> reporting connecting stopping",
    "reporting      -> connecting backoff stopping",
    "stopping       ->",
};

S ByName(const std::string& name) {
  for (size_t i = 0; i < kStateCount; ++i)
    if (name == StateName(S(i))) return S(i);
  ADD_FAILURE() << "no state named " << name;
  return S::kStopping;
}

const std::set<std::pair<S, S>>& LegalMoves() {
  static const std::set<std::pair<S, S>> moves = [] {
    std::set<std::pair<S, S>> m;
    for (const char* line : kDiagram) {
      std::istringstream in(line);
      std::string from, arrow, to;
      in >> from >> arrow;
      while (in >> to) m.insert({ByName(from), ByName(to)});
    }
    return m;
  }();
  return moves;
}

TEST(WorkerStateTest, EveryLegalMoveIsAccepted) {
  ASSERT_EQ(LegalMoves().size(), 26u);
  for (const auto& [from, to] : LegalMoves()) {
    EXPECT_TRUE(WorkerTransitions().Allows(from, to)) << StateName(from) << " -> " << StateName(to);
    EXPECT_NO_THROW(WorkerTransitions().Check(from, to)) << StateName(from) << " -> " << StateName(to);
    State s = from;
    WorkerTransitions().Move(s, to);
    EXPECT_EQ(s, to);
  }
}

TEST(WorkerStateTest, EveryOtherMoveThrows) {
  int refused = 0;
  for (size_t f = 0; f < kStateCount; ++f) {
    for (size_t t = 0; t < kStateCount; ++t) {
      const S from = S(f), to = S(t);
      if (LegalMoves().count({from, to})) continue;
      ++refused;
      EXPECT_FALSE(WorkerTransitions().Allows(from, to)) << StateName(from) << " -> " << StateName(to);
      EXPECT_THROW(WorkerTransitions().Check(from, to), std::logic_error)
          << StateName(from) << " -> " << StateName(to);
    }
  }
  EXPECT_EQ(refused, int(kStateCount * kStateCount - LegalMoves().size()));
}

TEST(WorkerStateTest, AnIllegalMoveNamesBothStatesAndLeavesTheStateAlone) {
  State s = S::kIdle;
  try {
    WorkerTransitions().Move(s, S::kReporting);  // a result reported without a task
    FAIL() << "idle -> reporting was accepted";
  } catch (const std::logic_error& e) {
    EXPECT_NE(std::string(e.what()).find("idle → reporting"), std::string::npos) << e.what();
    EXPECT_NE(std::string(e.what()).find("worker"), std::string::npos) << e.what();
  }
  EXPECT_EQ(s, S::kIdle);
}

TEST(WorkerStateTest, StoppingIsFinal) {
  for (size_t t = 0; t < kStateCount; ++t)
    EXPECT_FALSE(WorkerTransitions().Allows(S::kStopping, S(t))) << StateName(S(t));
}

TEST(WorkerStateTest, NamesAreTheLoggedOnes) {
  EXPECT_STREQ(StateName(S::kConnecting), "connecting");
  EXPECT_STREQ(StateName(S::kBackoff), "backoff");
  EXPECT_STREQ(StateName(S::kIdle), "idle");
  EXPECT_STREQ(StateName(S::kFetchingScene), "fetching-scene");
  EXPECT_STREQ(StateName(S::kBuildingMap), "building-map");
  EXPECT_STREQ(StateName(S::kRendering), "rendering");
  EXPECT_STREQ(StateName(S::kReporting), "reporting");
  EXPECT_STREQ(StateName(S::kStopping), "stopping");
}

}  // namespace
}  // namespace pf::worker
