#pragma once
// WatchJob: one server-streaming session per watcher, fed by the scheduler's change listener.
//
// A session sends an update at once, then one whenever the job changed (a merge, a lease, a state
// change), at most one per min_interval_seconds (0 = 0.5 s): changes in between are coalesced
// into the next update, which the coordinator's tick (WatchHub::Tick) sends when the interval has
// passed. With include_images every update carries an EXR snapshot of the merged image; a
// snapshot larger than 1 MiB spans several consecutive updates (ImageChunk index 0..count−1, the
// same status in each; concatenate the chunks). The stream ends (OK) after the update that
// carries the job's final state. Snapshots are resolved and encoded on the Executor, never on a
// gRPC thread; at most one snapshot per session is in flight and one write is outstanding.
//
// Lifetime: the gRPC reactor owns a shared session; the hub holds weak references. A session
// calls StartWrite/Finish only while it has not finished, and the reactor is deleted (OnDone)
// only after Finish, so the session never touches a dead reactor.
//
// Budgets (server/rpc/budgets.h, docs/security.md "Budgets"): at most watchers_per_client open
// streams per client and watchers_total in all (more: RESOURCE_EXHAUSTED before the first
// snapshot). A client that does not read holds at most one update's snapshot here — nothing new
// is built while a write is outstanding — and gRPC's flow-control window of bytes; a write not
// taken within watch_unread_seconds ends the stream (the call is cancelled, logged as a warning).

#include <map>
#include <memory>
#include <mutex>
#include <string>

#include <grpcpp/support/server_callback.h>

#include "photonfarm/v1/farm.pb.h"
#include "server/clock.h"
#include "server/executor.h"
#include "server/rpc/budgets.h"
#include "server/scheduling/scheduler.h"

namespace pf::server {

class WatchSession;

class WatchHub {
 public:
  WatchHub(Scheduler& scheduler, Executor& executor, const Clock& clock, const Budgets& budgets);

  // The reactor for one WatchJob call from `client` (ClientOf; precheck: e.g. the auth result).
  // `context` is the call's: an unread stream is cancelled through it.
  grpc::ServerWriteReactor<photonfarm::v1::JobUpdate>* Open(grpc::CallbackServerContext* context,
                                                            const std::string& client,
                                                            const photonfarm::v1::WatchJobRequest& request,
                                                            const grpc::Status& precheck);
  // Something changed in `job_id` (the scheduler's change listener).
  void Notify(const std::string& job_id);
  // Sends coalesced updates whose interval has passed and ends streams whose client has not read
  // for watch_unread_seconds. Called by the coordinator's tick.
  void Tick();
  // Ends every session with UNAVAILABLE (coordinator shutting down).
  void Shutdown();
  size_t sessions();

 private:
  struct Entry {
    std::string client;
    std::weak_ptr<WatchSession> session;
  };
  Scheduler& scheduler_;
  Executor& executor_;
  const Clock& clock_;
  const uint64_t per_client_, total_;
  const double unread_seconds_;
  std::mutex mu_;
  std::multimap<std::string, Entry> sessions_;  // by job id
  bool shutdown_ = false;
};

}  // namespace pf::server
