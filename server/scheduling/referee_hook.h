#pragma once
// The scheduler's referee (docs/farm.md "Result verification"): when a verification's result
// differs from the result it checks, or no worker is left to verify it, the coordinator renders the
// task itself and the scheduler convicts every worker whose digest differs from the referee's.
// Implemented by Referee (referee.h: ExecuteTask on a thread of its own); a test implements it to
// answer as it likes.

#include <cstdint>
#include <memory>
#include <string>

#include "common/plan/task_plan.h"

namespace pf::server {

struct JobConfig;

// A task the referee renders: answer Scheduler::RefereeVerdict(verification_id, …).
struct RefereeCase {
  uint64_t verification_id = 0;
  std::string job_id;
  TaskSpec task;
  std::shared_ptr<const JobConfig> config;
};

class RefereeHook {
 public:
  virtual ~RefereeHook() = default;
  // Called outside the scheduler's locks. Must not render on the caller's thread (an RPC's, or the
  // tick's): the render goes elsewhere and answers when it is done.
  virtual void Judge(RefereeCase c) = 0;
};

}  // namespace pf::server
