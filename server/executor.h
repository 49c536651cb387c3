#pragma once
// A small pool of threads for the work an RPC must not do on a gRPC callback thread (docs/design.md, S4;
// "reactors only validate and enqueue, never block"): loading an uploaded scene, writing a new
// job to SQLite, encoding an EXR, reading a scene bundle from disk. The reactor posts the work and
// returns; the work finishes the reactor.
//
// Bounded: Post returns false when `max_queue` tasks wait (the RPC answers UNAVAILABLE). Stop runs
// what is queued, then joins.

#include <condition_variable>
#include <deque>
#include <functional>
#include <mutex>
#include <thread>
#include <vector>

namespace pf::server {

class Executor {
 public:
  explicit Executor(size_t threads, size_t max_queue = 1024);
  ~Executor();  // Stop()
  bool Post(std::function<void()> work);
  void Stop();

 private:
  void Loop();
  std::mutex mu_;
  std::condition_variable cv_;
  std::deque<std::function<void()>> queue_;
  std::vector<std::thread> threads_;
  size_t max_queue_;
  bool stop_ = false;
};

}  // namespace pf::server
