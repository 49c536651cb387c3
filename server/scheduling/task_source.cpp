#include "server/scheduling/task_source.h"

namespace pf::server {

std::unique_ptr<TaskSource> MakeTaskSource(const JobConfig&) {
  return std::make_unique<StaticTaskSource>();
}

}  // namespace pf::server
