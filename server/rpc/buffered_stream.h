#pragma once
// A server-streaming reactor that makes its messages one at a time: GetImage (EXR chunks) and
// FetchScene (file chunks). `open` runs on the Executor (it may resolve and encode an image or
// list stored files) and returns a source; each message is then read from the source on the
// Executor once the previous one has been written, and the call finishes OK at the source's end
// — or with an error mapped by StatusFromException. A stream thus holds one message (≤ 1 MiB)
// whatever the size of the answer: twenty unread streams of a 60 MiB scene used to hold 1.35 GB
// (docs/farm.md, "Photon maps traced once"); now they hold twenty chunks, and the files stay on disk.

#include <functional>
#include <string>
#include <utility>

#include <grpcpp/support/server_callback.h>

#include "server/executor.h"
#include "server/rpc/status_mapping.h"

namespace pf::server {

template <typename T>
class ChunkedStreamReactor final : public grpc::ServerWriteReactor<T> {
 public:
  // Fills *message with the next message and returns true, or returns false at the end.
  using Source = std::function<bool(T* message)>;
  using Opener = std::function<Source()>;

  // `precheck` not OK: finish at once with it (e.g. UNAUTHENTICATED).
  static grpc::ServerWriteReactor<T>* Start(Executor& executor, std::string rpc, const grpc::Status& precheck,
                                            Opener open) {
    auto* r = new ChunkedStreamReactor(executor, std::move(rpc));
    if (!precheck.ok()) {
      r->Finish(precheck);
      return r;
    }
    if (!executor.Post([r, o = std::move(open)] { r->Open(o); }))
      r->Finish(grpc::Status(grpc::StatusCode::UNAVAILABLE, "coordinator busy or shutting down"));
    return r;
  }

  void OnWriteDone(bool ok) override {
    if (!ok) {
      this->Finish(grpc::Status(grpc::StatusCode::CANCELLED, "stream closed by the client"));
      return;
    }
    if (!executor_.Post([this] { Next(); }))
      this->Finish(grpc::Status(grpc::StatusCode::UNAVAILABLE, "coordinator busy or shutting down"));
  }
  void OnDone() override { delete this; }

 private:
  ChunkedStreamReactor(Executor& executor, std::string rpc) : executor_(executor), rpc_(std::move(rpc)) {}

  void Open(const Opener& open) {
    const grpc::Status status = Guarded(rpc_, [&] {
      source_ = open();
      return grpc::Status::OK;
    });
    if (!status.ok()) {
      this->Finish(status);
      return;
    }
    Next();
  }
  void Next() {
    bool more = false;
    const grpc::Status status = Guarded(rpc_, [&] {
      message_.Clear();
      more = source_(&message_);
      return grpc::Status::OK;
    });
    if (!status.ok()) {
      this->Finish(status);
      return;
    }
    if (!more) {
      source_ = nullptr;  // closes files now rather than when gRPC lets go of the reactor
      this->Finish(grpc::Status::OK);
      return;
    }
    this->StartWrite(&message_);
  }

  Executor& executor_;
  std::string rpc_;
  Source source_;
  T message_;
};

}  // namespace pf::server
