// Fuzz target: the server's request handlers (physics_service.cpp) called in process, as gRPC
// calls them, with a sequence of arbitrary request messages: CreateWorld, ListWorlds, GetWorld,
// DeleteWorld, ApplyEdits, Step, GetSnapshot, RestoreSnapshot, Query and GetStats. Streams,
// real time and recordings are left to the server's own tests.
//
// Input: calls, each a method byte, a two-byte little-endian length and that many bytes of the
// method's request message. A world_id of 1 to 16 names the 1st to 16th world this input
// created (so that seeds and mutations reach live worlds); other ids go through as they are.
// Checks after every call: a refused call changed no world (same worlds, ticks and hashes) and
// its status has a message; every world passes check_world (through its snapshot, as a client
// would fetch it).
#include <grpcpp/grpcpp.h>

#include <map>
#include <utility>
#include <vector>

#include "fuzz_server.h"
#include "fuzz_support.h"
#include "physics_service.h"
#include "session.h"
#include "snapshot_convert.h"

namespace {

using namespace fulcrum;
using server::PhysicsService;
using server::Registry;

server::Limits fuzz_server_limits() {
  server::Limits l;
  const EditLimits e = fuzz::limits();
  l.max_worlds = 4;
  l.max_bodies = e.max_bodies;
  l.max_shapes = e.max_shapes;
  l.max_shapes_per_body = e.max_shapes_per_body;
  l.max_batch_work = e.max_work;
  l.max_edits = e.max_edits;
  l.max_contacts = 4096;
  l.max_step_ticks = 8;
  return l;
}

struct Service {
  Registry registry{fuzz_server_limits()};
  PhysicsService service{&registry, ""};
};

// Points a small world_id at a world this input created.
void map_world_id(google::protobuf::Message* request, const std::vector<uint64_t>& created) {
  const google::protobuf::FieldDescriptor* field =
      request->GetDescriptor()->FindFieldByName("world_id");
  if (field == nullptr || field->type() != google::protobuf::FieldDescriptor::TYPE_UINT64) return;
  const google::protobuf::Reflection* r = request->GetReflection();
  const uint64_t id = r->GetUInt64(*request, field);
  if (id >= 1 && id <= 16 && !created.empty()) {
    r->SetUInt64(request, field, created[(id - 1) % created.size()]);
  }
}

template <typename Request, typename Reply, typename Handler>
grpc::Status call(Service& s, std::string_view bytes, const std::vector<uint64_t>& created,
                  Handler handler, Reply* reply) {
  Request request;
  if (!request.ParseFromArray(bytes.data(), static_cast<int>(bytes.size()))) {
    return grpc::Status(grpc::StatusCode::INVALID_ARGUMENT, "does not parse");
  }
  map_world_id(&request, created);
  fuzz::print(request);
  grpc::ServerContext context;
  return (s.service.*handler)(&context, &request, reply);
}

void check_worlds(Registry& registry) {
  for (const auto& session : registry.list()) {
    v1::GetSnapshotReply snapshot;
    session->snapshot(&snapshot);
    World copy{WorldSettings{}};
    Status s = restore_encoded(&copy, snapshot.snapshot().SerializeAsString());
    fuzz::check(s.ok(), "world " + std::to_string(session->id()) +
                            "'s snapshot does not restore: " + s.message());
    fuzz::check_world(copy, "world " + std::to_string(session->id()));
  }
}

}  // namespace

extern "C" int LLVMFuzzerTestOneInput(const uint8_t* data, size_t size) {
  static Service* s = new Service;  // one service for the process, as in the server
  std::vector<uint64_t> created;
  size_t pos = 0;
  while (pos + 3 <= size) {
    const int method = data[pos] % 10;
    const size_t len = std::min<size_t>(data[pos + 1] | (data[pos + 2] << 8), size - pos - 3);
    const std::string_view bytes = fuzz::bytes(data + pos + 3, len);
    pos += 3 + len;
    const auto before = fuzz::worlds(s->registry);
    grpc::Status status;
    switch (method) {
      case 0: {
        v1::CreateWorldReply reply;
        status =
            call<v1::CreateWorldRequest>(*s, bytes, created, &PhysicsService::CreateWorld, &reply);
        if (status.ok()) created.push_back(reply.world_id());
        break;
      }
      case 1: {
        v1::ListWorldsReply reply;
        status =
            call<v1::ListWorldsRequest>(*s, bytes, created, &PhysicsService::ListWorlds, &reply);
        break;
      }
      case 2: {
        v1::WorldInfo reply;
        status = call<v1::GetWorldRequest>(*s, bytes, created, &PhysicsService::GetWorld, &reply);
        break;
      }
      case 3: {
        v1::DeleteWorldReply reply;
        status =
            call<v1::DeleteWorldRequest>(*s, bytes, created, &PhysicsService::DeleteWorld, &reply);
        break;
      }
      case 4: {
        v1::ApplyEditsReply reply;
        status =
            call<v1::ApplyEditsRequest>(*s, bytes, created, &PhysicsService::ApplyEdits, &reply);
        break;
      }
      case 5: {
        v1::StepReply reply;
        status = call<v1::StepRequest>(*s, bytes, created, &PhysicsService::Step, &reply);
        break;
      }
      case 6: {
        v1::GetSnapshotReply reply;
        status =
            call<v1::GetSnapshotRequest>(*s, bytes, created, &PhysicsService::GetSnapshot, &reply);
        break;
      }
      case 7: {
        v1::RestoreSnapshotReply reply;
        status = call<v1::RestoreSnapshotRequest>(*s, bytes, created,
                                                  &PhysicsService::RestoreSnapshot, &reply);
        if (status.ok() && before.count(reply.world_id()) == 0) created.push_back(reply.world_id());
        break;
      }
      case 8: {
        v1::QueryReply reply;
        status = call<v1::QueryRequest>(*s, bytes, created, &PhysicsService::Query, &reply);
        break;
      }
      default: {
        v1::ServerStats reply;
        status = call<v1::GetStatsRequest>(*s, bytes, created, &PhysicsService::GetStats, &reply);
        break;
      }
    }
    if (!status.ok()) {
      fuzz::check(!status.error_message().empty(), "a refusal without a message");
      fuzz::check(fuzz::worlds(s->registry) == before,
                  "a refused call changed a world: " + status.error_message());
    }
    check_worlds(s->registry);
  }
  for (const auto& session : s->registry.list()) (void)s->registry.remove(session->id());
  return 0;
}
