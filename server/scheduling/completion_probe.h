#pragma once
// A seam inside Scheduler::Complete, injected through SchedulerOptions::probe: production passes
// none (nothing is called), tests pass theirs to expire, cancel or complete other leases while a
// result is in flight — between its check and its commit, with no lock held (scheduler.h, the
// three steps of Complete). A seam rather than a test-only setter, so production code carries no
// test hooks.

#include <string>

namespace pf::server {

class CompletionProbe {
 public:
  virtual ~CompletionProbe() = default;
  // Complete has checked the result of `lease_id` and is about to commit it.
  virtual void BeforeCommit(const std::string& lease_id) = 0;
};

}  // namespace pf::server
