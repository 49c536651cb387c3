#pragma once
// Faults a test injects into a real worker: where it stops (a kill point for SIGKILL tests), what
// it corrupts on arrival, what it changes before sending (a malicious worker). pf-worker never
// injects any (worker/main.cpp passes none); the test binaries do: tests/e2e/faulty_worker.cpp
// (kill points, a corrupted map part) and tests/e2e/fake_worker.cpp (tampered results and pieces),
// both running this worker's own loop (docs/farm.md, "Worker"; "Result verification").

#include <cstdint>
#include <string>
#include <vector>

namespace pf::worker {

class WorkerFaults {
 public:
  virtual ~WorkerFaults() = default;
  // At a step of a task: `where` is "trace" (before tracing a piece), "upload" (before sending
  // it), "fetch" (before fetching a built map) or "render" (before rendering a render task, its
  // scene and map at hand); `context` names the task. May block; the lease is kept alive.
  virtual void At(const char* /*where*/, const std::string& /*context*/) {}
  // A part of a fetched map as received, before its checks.
  virtual void OnMapPart(std::string& /*data*/, uint32_t /*index*/, const std::string& /*map_key*/) {}
  // A task's pixel sums, before they are sent.
  virtual void OnResult(std::vector<float>& /*rgb_sums*/) {}
  // A traced piece's bytes, before they are sent.
  virtual void OnPiece(std::string& /*piece_bytes*/) {}
};

}  // namespace pf::worker
