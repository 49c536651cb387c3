#pragma once
// A blocking unary call through gRPC's generic stub (raw bytes in, raw bytes out), for tests that
// call methods by name: the generic stub only offers the callback form.

#include <grpcpp/generic/generic_stub.h>

#include <condition_variable>
#include <mutex>
#include <string>

namespace pf::test_util {

// Calls `method` ("/package.Service/Method") with `request`; waits for the answer.
inline grpc::Status BlockingGenericCall(grpc::GenericStub& stub, grpc::ClientContext* ctx,
                                        const std::string& method, const grpc::ByteBuffer* request,
                                        grpc::ByteBuffer* response) {
  std::mutex mu;
  std::condition_variable cv;
  bool done = false;
  grpc::Status result;
  stub.UnaryCall(ctx, method, grpc::StubOptions(), request, response, [&](grpc::Status st) {
    std::lock_guard lock(mu);
    result = std::move(st);
    done = true;
    cv.notify_all();
  });
  std::unique_lock lock(mu);
  cv.wait(lock, [&] { return done; });
  return result;
}

}  // namespace pf::test_util
