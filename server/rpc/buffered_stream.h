#pragma once
// A server-streaming reactor for answers that are computed once and then streamed: GetImage
// (EXR chunks) and FetchScene (file chunks). The producer runs on the Executor (it may read
// files or encode an EXR); the messages are then written one after the other, each started from
// the previous one's OnWriteDone, and the call finishes OK — or with the producer's error mapped
// by StatusFromException.

#include <functional>
#include <string>
#include <utility>
#include <vector>

#include <grpcpp/support/server_callback.h>

#include "server/rpc/executor.h"
#include "server/rpc/status_mapping.h"

namespace pf::server {

template <typename T>
class BufferedStreamReactor final : public grpc::ServerWriteReactor<T> {
 public:
  using Producer = std::function<std::vector<T>()>;

  // `precheck` not OK: finish at once with it (e.g. UNAUTHENTICATED).
  static grpc::ServerWriteReactor<T>* Start(Executor& executor, std::string rpc, const grpc::Status& precheck,
                                            Producer producer) {
    auto* r = new BufferedStreamReactor(std::move(rpc));
    if (!precheck.ok()) {
      r->Finish(precheck);
      return r;
    }
    if (!executor.Post([r, p = std::move(producer)] { r->Produce(p); }))
      r->Finish(grpc::Status(grpc::StatusCode::UNAVAILABLE, "coordinator busy or shutting down"));
    return r;
  }

  void OnWriteDone(bool ok) override {
    if (!ok) {
      this->Finish(grpc::Status(grpc::StatusCode::CANCELLED, "stream closed by the client"));
      return;
    }
    WriteNext();
  }
  void OnDone() override { delete this; }

 private:
  explicit BufferedStreamReactor(std::string rpc) : rpc_(std::move(rpc)) {}

  void Produce(const Producer& producer) {
    const grpc::Status status = Guarded(rpc_, [&] {
      messages_ = producer();
      return grpc::Status::OK;
    });
    if (!status.ok()) {
      this->Finish(status);
      return;
    }
    WriteNext();
  }
  void WriteNext() {
    if (next_ == messages_.size()) {
      this->Finish(grpc::Status::OK);
      return;
    }
    this->StartWrite(&messages_[next_++]);
  }

  std::string rpc_;
  std::vector<T> messages_;
  size_t next_ = 0;
};

}  // namespace pf::server
