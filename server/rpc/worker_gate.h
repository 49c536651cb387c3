#pragma once
// WorkerService's credential check in its handlers (auth.h has the rule and says which calls
// RoleAuthProcessor leaves to it: those from this machine or with a verified client
// certificate). Every WorkerService handler admits its call here before it reads anything else of
// it; here the caller's address is known, and refusals are counted per address
// (FarmActivity::WorkerRefused; pf workers). A test calls every method of the service's
// descriptor without the credential, so a handler that forgot the gate fails it.

#include <grpcpp/support/server_callback.h>

#include <string>
#include <string_view>

#include "server/rpc/auth.h"

namespace pf::server {

class WorkerGate {
 public:
  WorkerGate(RoleTokens tokens, bool needs_certificate, OnWorkerRefused on_refused = {})
      : tokens_(std::move(tokens)),
        needs_certificate_(needs_certificate),
        on_refused_(std::move(on_refused)) {}

  // OK, or the refusal (UNAUTHENTICATED, PERMISSION_DENIED for the client credential), reported
  // to `on_refused` first.
  grpc::Status Admit(const grpc::CallbackServerContext& context) const;

 private:
  RoleTokens tokens_;
  bool needs_certificate_;
  OnWorkerRefused on_refused_;
};

}  // namespace pf::server
