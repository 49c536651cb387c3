#include "worker/leased_task.h"

#include "proto/convert.h"

namespace pf::worker {
namespace v1 = photonfarm::v1;

ParsedTask ParseTask(const v1::Task& task) {
  ParsedTask parsed;
  parsed.camera = CameraFromProto(task.camera(), "task.camera");
  parsed.settings = SettingsFromProto(task.settings(), "task.settings");
  parsed.spec = TaskSpecFromProto(task);
  return parsed;
}

uint64_t CountTaskPixels(const ParsedTask& parsed) {
  return CountPixels(parsed.spec.pixels, parsed.camera.width, parsed.camera.height);
}

std::string TaskContext(const v1::Task& t) {
  return "job=" + t.job_id() + " task=" + std::to_string(t.task_id()) +
         " attempt=" + std::to_string(t.attempt());
}

std::string PieceContext(const v1::Task& t) {
  const v1::TraceChunk& piece = t.trace_chunk();
  return "job=" + t.job_id() + " map=" + std::to_string(t.map_index()) +
         " piece=" + std::to_string(piece.chunk_index()) + "/" + std::to_string(piece.chunk_count()) +
         " attempt=" + std::to_string(t.attempt());
}

}  // namespace pf::worker
