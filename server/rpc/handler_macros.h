#pragma once
// The overrides of generated callback-API handlers (photonfarm.v1 services), spelled once so that
// the service headers list only what differs: method, request and response (or streamed item).

#include <grpcpp/support/server_callback.h>

// grpc::ServerUnaryReactor* Method(context, const Request* request, Response* response) override
#define PF_UNARY_HANDLER(Method, Request, Response)                        \
  grpc::ServerUnaryReactor* Method(grpc::CallbackServerContext* context,   \
                                   const photonfarm::v1::Request* request, \
                                   photonfarm::v1::Response* response) override

// grpc::ServerWriteReactor<Item>* Method(context, const Request* request) override
#define PF_STREAM_HANDLER(Method, Request, Item)                                               \
  grpc::ServerWriteReactor<photonfarm::v1::Item>* Method(grpc::CallbackServerContext* context, \
                                                         const photonfarm::v1::Request* request) override
