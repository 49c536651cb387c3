// The Scheduler's one queue (server/scheduling/task_queue.h), on its own: map pieces by their map's
// creation order and index, a map passed over by the filter (a worker blocklisted in one of its
// jobs), pieces leaving the queue when leased or when their map's pieces are set again, and render
// tasks of a held job passed over while pieces are not held. That pieces are served before render
// tasks is the Scheduler's order (scheduler_test.cpp, distributed_maps_test.cpp).
#include "server/scheduling/task_queue.h"

#include <gtest/gtest.h>

#include <memory>
#include <vector>

#include "server/scheduling/scheduler.h"
#include "tests/server/server_test_util.h"

namespace pf::server {
namespace {

using testing::MakeConfig;
using testing::MultipleMaps;

std::vector<uint32_t> Indices(std::initializer_list<uint32_t> list) {
  return std::vector<uint32_t>(list);
}

TEST(TaskQueueTest, PiecesOfTheOldestMapFirstThenTheLowestPiece) {
  TaskQueue queue;
  EXPECT_TRUE(queue.empty());
  EXPECT_FALSE(queue.ChoosePiece().has_value());
  queue.SetMapPieces("newer", 5, Indices({0}));
  queue.SetMapPieces("older", 2, Indices({4, 1}));
  queue.SetMapPieces("none", 1, {});  // a map without queued pieces is not in the queue
  EXPECT_FALSE(queue.empty()) << "pieces are queued work";
  EXPECT_EQ(queue.queued_pieces(), 3u);
  std::vector<std::pair<std::string, uint32_t>> order;
  while (const std::optional<TaskQueue::Piece> p = queue.ChoosePiece()) {
    order.emplace_back(p->map_key, p->index);
    queue.RemovePiece(p->map_seq, p->index);  // leased: it leaves the queue
  }
  const std::vector<std::pair<std::string, uint32_t>> expected = {{"older", 1}, {"older", 4}, {"newer", 0}};
  EXPECT_EQ(order, expected);
  EXPECT_TRUE(queue.empty());
  EXPECT_FALSE(queue.has_pieces());
}

TEST(TaskQueueTest, AMapTheFilterRefusesIsPassedOver) {
  TaskQueue queue;
  queue.SetMapPieces("a", 1, Indices({0, 1}));
  queue.SetMapPieces("b", 2, Indices({3}));
  const auto not_a = [](const std::string& key) { return key != "a"; };
  const std::optional<TaskQueue::Piece> p = queue.ChoosePiece(not_a);
  ASSERT_TRUE(p.has_value());
  EXPECT_EQ(p->map_key, "b");
  EXPECT_EQ(p->map_seq, 2u);
  EXPECT_EQ(p->index, 3u);
  EXPECT_FALSE(queue.ChoosePiece([](const std::string&) { return false; }).has_value());
  EXPECT_EQ(queue.ChoosePiece()->map_key, "a") << "the filter removes nothing";
}

TEST(TaskQueueTest, SettingAMapsPiecesReplacesThemAndRemovalIsIdempotent) {
  TaskQueue queue;
  queue.SetMapPieces("a", 1, Indices({0, 1, 2}));
  queue.RemovePiece(1, 1);
  queue.RemovePiece(1, 1);  // not queued: nothing
  queue.RemovePiece(9, 0);  // unknown map: nothing
  EXPECT_EQ(queue.queued_pieces(), 2u);
  queue.SetMapPieces("a", 1, Indices({2}));  // e.g. piece 0 leased meanwhile
  EXPECT_EQ(queue.queued_pieces(), 1u);
  EXPECT_EQ(queue.ChoosePiece()->index, 2u);
  queue.SetMapPieces("a", 1, {});  // left to the workers: its pieces leave the queue
  EXPECT_TRUE(queue.empty());
}

TEST(TaskQueueTest, AHeldJobsTasksArePassedOverButPiecesAreNotHeld) {
  FakeClock clock;
  Scheduler scheduler(clock, SchedulerOptions{});
  std::unique_ptr<Job> first = scheduler.PrepareJob(MakeConfig(MultipleMaps(1, 4), 4, 4));
  std::unique_ptr<Job> second = scheduler.PrepareJob(MakeConfig(MultipleMaps(1, 4), 4, 4));
  TaskQueue queue;
  queue.Push(*first, 0);
  queue.Push(*second, 0);
  queue.SetMapPieces("map", 1, Indices({0}));
  EXPECT_EQ(queue.NextJob(std::nullopt), first.get()) << "submission order";
  queue.Hold(*first);
  EXPECT_EQ(queue.NextJob(std::nullopt), second.get()) << "a held job is passed over";
  EXPECT_EQ(queue.NextJob(TaskQueue::PositionOf(*second)), nullptr);
  ASSERT_TRUE(queue.ChoosePiece().has_value()) << "pieces may serve other jobs: not held";
  queue.Remove(*second, 0);
  EXPECT_FALSE(queue.empty()) << "the piece is still queued";
  queue.RemovePiece(1, 0);
  EXPECT_TRUE(queue.empty()) << "only the held job's task is left";
  EXPECT_TRUE(queue.Unhold(*first));
  EXPECT_EQ(queue.NextJob(std::nullopt), first.get());
}

}  // namespace
}  // namespace pf::server
