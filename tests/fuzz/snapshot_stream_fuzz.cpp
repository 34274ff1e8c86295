// Fuzz target: the calls that stream what a unary call would return whole: snapshots in chunks,
// both ways (DownloadSnapshot, RestoreSnapshotStream), and StepTrajectory, through a server
// started once per process on a loopback port (the upload reads its chunks from a gRPC stream,
// so it is driven as a client drives it).
//
// Input: a byte of set-up, with bit 6 a StepTrajectory call first (a two-byte little-endian
// length and that many bytes of StepTrajectoryRequest; a world_id of 1 names the world), then
// chunks of 12 bytes each, sent in order on one upload:
//   set-up: bits 0-1 the base world the server's world starts from (bridge, mixed, bounce:
//     fuzz_worlds.h; the ragdolls are left out, too slow here); bit 2 the upload rolls that world
//     back (world_id its id) rather than forking a new world; bit 3 the world is downloaded
//     first; bits 4-5 the base world whose snapshot (5 ticks on) the upload carries.
//   chunk: flags (bit 0 the first chunk's fields: world_id, name, total_size; bit 1 last; bit 2
//     the checksum right for the bytes sent so far, else `value`; bit 3 total_size right, else
//     `value`; bit 4 no chunk at all; bit 5 world_id `value` instead of the world's; bit 6 a
//     name; bit 7 64 KiB more data), a signed 16-bit offset from the bytes sent so far, a 16-bit
//     size (the snapshot's bytes from the offset, zeros past its end), a byte to xor into the
//     data (0: none) and a 16-bit position for it, and a 32-bit value.
//
// Checks: the server's verdict is the framing rules' (total_size first, in the limit; offsets
// contiguous; at most 64 KiB a chunk; nothing past total_size or after the last chunk; the
// checksum of all the bytes): a sequence the rules refuse is refused with a message naming the
// chunk and field, and no world changes (same worlds, ticks and hashes); a sequence that carries
// the snapshot unchanged restores exactly that snapshot (its tick and hash, into the world or a
// new one); damaged bytes behind a right checksum are refused without a change, or restore what
// a local restore of the same bytes gives. A download's chunks obey the same rules, carry the
// world's tick and hash, and restore to it. A trajectory that is refused names a field and
// changes nothing; an accepted one steps the world exactly its ticks, with a sample at each
// multiple of every_ticks whose hash is the one a local copy of the world has at that tick, and
// `done` the world after the last.
#include <grpcpp/grpcpp.h>

#include <algorithm>
#include <array>
#include <map>
#include <memory>
#include <string>
#include <utility>
#include <vector>

#include "fulcrum/v1/service.grpc.pb.h"
#include "fuzz_server.h"
#include "fuzz_support.h"
#include "fuzz_worlds.h"
#include "server.h"
#include "session.h"
#include "snapshot_convert.h"

namespace {

using namespace fulcrum;

constexpr size_t kChunkBytes = 64 * 1024;  // the server's largest chunk (physics_service.cpp)
constexpr int64_t kMaxSnapshotBytes = 1 << 20;
constexpr uint8_t kBases[] = {0, 2, 3};  // bridge, mixed, bounce

// FNV-1a 64 carried on from `h` (the offset basis for none yet): the checksum of the bytes sent
// so far, one chunk at a time.
uint64_t fnv_continue(uint64_t h, std::string_view bytes) {
  for (unsigned char c : bytes) {
    h ^= c;
    h *= 0x100000001b3ull;
  }
  return h;
}

struct Harness {
  std::unique_ptr<server::Server> server;
  std::unique_ptr<v1::Physics::Stub> stub;
  std::array<std::string, 3> payloads;  // each base world 5 ticks on, as SnapshotFile bytes
  std::array<std::pair<int64_t, uint64_t>, 3> payload_states;  // their tick and hash
};

Harness* start() {
  auto* h = new Harness;
  server::ServerOptions options;
  options.listen = "127.0.0.1:0";
  options.reflection = false;
  options.worker_threads = 1;
  options.limits.max_worlds = 8;
  options.limits.max_snapshot_bytes = kMaxSnapshotBytes;
  options.limits.max_step_ticks = 64;
  Result<std::unique_ptr<server::Server>> started = server::Server::start(options);
  fuzz::check(started.ok(), "the server starts: " + started.status().message());
  h->server = std::move(started).value();
  h->stub = v1::Physics::NewStub(
      grpc::CreateChannel(h->server->address(), grpc::InsecureChannelCredentials()));
  for (uint8_t i = 0; i < 3; ++i) {
    World w = fuzz::base_world(kBases[i]);
    for (int t = 0; t < 5; ++t) w.step();
    h->payloads[i] = encode_snapshot(w);
    h->payload_states[i] = {w.tick(), w.state_hash()};
  }
  return h;
}

uint64_t read_le(const uint8_t* p, int bytes) {
  uint64_t v = 0;
  for (int i = 0; i < bytes; ++i) v |= uint64_t{p[i]} << (8 * i);
  return v;
}

std::unique_ptr<grpc::ClientContext> context() {
  auto c = std::make_unique<grpc::ClientContext>();
  c->set_deadline(std::chrono::system_clock::now() + std::chrono::seconds(30));
  return c;
}

// DownloadSnapshot of `world`: the chunks obey the upload's rules and restore to the world.
void check_download(Harness& h, uint64_t world, std::pair<int64_t, uint64_t> state) {
  auto ctx = context();
  v1::GetSnapshotRequest request;
  request.set_world_id(world);
  auto reader = h.stub->DownloadSnapshot(ctx.get(), request);
  v1::SnapshotChunk chunk;
  std::string bytes;
  uint64_t total = 0;
  bool last = false;
  uint64_t checksum = 0;
  for (int i = 0; reader->Read(&chunk); ++i) {
    fuzz::check(!last, "download: a chunk after the last");
    if (i == 0) {
      total = chunk.total_size();
      fuzz::check(chunk.tick() == state.first && chunk.state_hash() == state.second,
                  "download: the first chunk's tick and hash are not the world's");
    } else {
      fuzz::check(chunk.total_size() == 0 && chunk.tick() == 0,
                  "download: first-chunk fields in a later chunk");
    }
    fuzz::check(chunk.offset() == bytes.size() && chunk.data().size() <= kChunkBytes,
                "download: a chunk out of place or too large");
    bytes += chunk.data();
    last = chunk.last();
    checksum = chunk.checksum();
  }
  grpc::Status s = reader->Finish();
  fuzz::check(s.ok(), "download: " + s.error_message());
  fuzz::check(last && bytes.size() == total && checksum == fnv1a64(bytes),
              "download: no last chunk, or the size or checksum is wrong");
  World copy{WorldSettings{}};
  Status restored = restore_encoded(&copy, bytes);
  fuzz::check(restored.ok(), "download: does not restore: " + restored.message());
  fuzz::check(copy.tick() == state.first && copy.state_hash() == state.second,
              "download: restores to another world");
  fuzz::check_world(copy, "download");
}

// StepTrajectory on `world`, a copy of `base` (the same base world): checked against `base`
// stepped here.
void check_trajectory(Harness& h, uint64_t world, World base, std::string_view bytes) {
  v1::StepTrajectoryRequest request;
  if (!request.ParseFromArray(bytes.data(), static_cast<int>(bytes.size()))) return;
  if (request.world_id() == 1) request.set_world_id(world);
  fuzz::print(request);
  server::Registry& registry = h.server->registry();
  const auto before = fuzz::worlds(registry);
  auto ctx = context();
  auto reader = h.stub->StepTrajectory(ctx.get(), request);
  std::vector<v1::TrajectorySample> samples;
  std::vector<v1::StepReply> done;
  v1::TrajectoryChunk chunk;
  while (reader->Read(&chunk)) {
    for (const v1::TrajectorySample& s : chunk.samples()) samples.push_back(s);
    if (chunk.has_done()) done.push_back(chunk.done());
  }
  const grpc::Status status = reader->Finish();
  if (std::getenv("FULCRUM_FUZZ_PRINT") != nullptr) {
    std::fprintf(stderr, "-> %s, %zu samples\n",
                 status.ok() ? "OK" : status.error_message().c_str(), samples.size());
  }
  if (!status.ok()) {
    // Nothing here stops a trajectory part way (no deadline passes, no contact limit is near),
    // so a refusal comes before the first tick.
    fuzz::check(samples.empty() && done.empty(),
                "trajectory: refused after it ran: " + status.error_message());
    const std::string& message = status.error_message();
    fuzz::check(message.rfind("ticks:", 0) == 0 || message.rfind("bodies", 0) == 0 ||
                    message.rfind("expected_tick:", 0) == 0 || message.rfind("world_id:", 0) == 0,
                "trajectory: a refusal that names no field: " + message);
    fuzz::check(fuzz::worlds(registry) == before,
                "trajectory: a refusal changed a world: " + message);
    return;
  }
  fuzz::check(request.world_id() == world, "trajectory: accepted for another world");
  const uint32_t every = request.every_ticks() == 0 ? 1 : request.every_ticks();
  const size_t bodies =
      request.bodies().empty() ? static_cast<size_t>(base.body_count()) : request.bodies().size();
  const size_t expected = request.ticks() / every + (request.include_start() ? 1 : 0);
  fuzz::check(samples.size() == expected, "trajectory: " + std::to_string(samples.size()) +
                                              " samples, expected " + std::to_string(expected));
  size_t next = 0;
  const int64_t start = base.tick();
  for (uint32_t t = 0; t <= request.ticks(); ++t) {
    if (t > 0) base.step();
    if ((t == 0 && !request.include_start()) || (t > 0 && t % every != 0)) continue;
    const v1::TrajectorySample& s = samples.at(next++);
    fuzz::check(s.tick() == start + t && s.state_hash() == base.state_hash() &&
                    static_cast<size_t>(s.bodies_size()) == bodies,
                "trajectory: the sample at tick " + std::to_string(start + t) +
                    " is not the world stepped here");
  }
  fuzz::check(done.size() == 1 && done[0].tick() == base.tick() &&
                  done[0].state_hash() == base.state_hash(),
              "trajectory: done is not the world after the last tick");
  fuzz::check(fuzz::worlds(registry).at(world) == std::make_pair(base.tick(), base.state_hash()),
              "trajectory: the world is not where done says");
}

}  // namespace

extern "C" int LLVMFuzzerTestOneInput(const uint8_t* data, size_t size) {
  static Harness* h = start();  // one server for the process
  if (size < 1) return 0;
  server::Registry& registry = h->server->registry();
  const uint8_t setup = data[0];
  Result<std::shared_ptr<server::Session>> target =
      registry.create("fuzz", fuzz::base_world(kBases[(setup & 3) % 3]));
  fuzz::check(target.ok(), "the world is created: " + target.status().message());
  const uint64_t world = (*target)->id();
  size_t pos = 1;
  if ((setup & 0x40) != 0 && size >= 3) {
    const size_t length = std::min<size_t>(read_le(data + 1, 2), size - 3);
    check_trajectory(*h, world, fuzz::base_world(kBases[(setup & 3) % 3]),
                     fuzz::bytes(data + 3, length));
    pos = 3 + length;
  }
  const bool rollback = (setup & 4) != 0;
  const size_t source = ((setup >> 4) & 3) % 3;
  const std::string& payload = h->payloads[source];
  const auto before = fuzz::worlds(registry);
  if ((setup & 8) != 0) check_download(*h, world, before.at(world));

  // The upload, and the framing rules' verdict on it.
  std::vector<v1::RestoreSnapshotChunk> messages;
  std::string sent;     // the data of every chunk, in order
  std::string framing;  // empty: the rules accept the sequence so far
  bool last = false;
  uint64_t total = 0, checksum = 0;
  uint64_t running = fnv_continue(0xcbf29ce484222325ull, "");
  for (; pos + 12 <= size; pos += 12) {
    const uint8_t* op = data + pos;
    const uint8_t flags = op[0];
    const int64_t offset_delta = static_cast<int16_t>(read_le(op + 1, 2));
    size_t length = read_le(op + 3, 2) + ((flags & 0x80) != 0 ? kChunkBytes : 0);
    const uint8_t flip = op[5];
    const size_t flip_at = read_le(op + 6, 2);
    const uint64_t value = read_le(op + 8, 4);
    const size_t i = messages.size();
    v1::RestoreSnapshotChunk& m = messages.emplace_back();
    if ((flags & 0x40) != 0) m.set_name("fork");
    if ((flags & 0x10) != 0) {
      if (framing.empty()) framing = "no chunk";
      continue;
    }
    v1::SnapshotChunk* chunk = m.mutable_chunk();
    if ((flags & 1) != 0) {
      m.set_world_id((flags & 0x20) != 0 ? value : (rollback ? world : 0));
      chunk->set_total_size((flags & 8) != 0 ? payload.size() : value);
    }
    const int64_t offset = static_cast<int64_t>(sent.size()) + offset_delta;
    chunk->set_offset(static_cast<uint64_t>(offset));
    std::string bytes = sent.size() < payload.size() ? payload.substr(sent.size(), length) : "";
    bytes.resize(length, '\0');
    if (flip != 0 && !bytes.empty()) {
      bytes[flip_at % bytes.size()] ^= static_cast<char>(flip);
    }
    chunk->set_data(bytes);
    chunk->set_last((flags & 2) != 0);
    const uint64_t sum = fnv_continue(running, bytes);
    chunk->set_checksum((flags & 4) != 0 ? sum : value);
    if (!framing.empty()) continue;
    if (last) {
      framing = "after the last";
    } else if (i == 0 && (chunk->total_size() == 0 ||
                          chunk->total_size() > static_cast<uint64_t>(kMaxSnapshotBytes))) {
      framing = "total_size";
    } else if (i > 0 && (m.world_id() != 0 || !m.name().empty() || chunk->total_size() != 0)) {
      framing = "first-chunk fields";
    } else if (offset != static_cast<int64_t>(sent.size()) || bytes.size() > kChunkBytes) {
      framing = "offset or size";
    } else if (sent.size() + bytes.size() > (i == 0 ? chunk->total_size() : total)) {
      framing = "past total_size";
    }
    if (i == 0) total = chunk->total_size();
    if (!framing.empty()) continue;
    sent += bytes;
    running = sum;
    last = chunk->last();
    checksum = chunk->checksum();
  }
  if (framing.empty() && (!last || sent.size() != total)) framing = "no last chunk, or short";
  fuzz::check(running == fnv1a64(sent), "the harness's running checksum");
  if (framing.empty() && checksum != running) framing = "checksum";
  // Bytes flipped, cut short or padded: a right checksum still lets them through to the decoder.
  const bool damaged = sent != payload;
  // What a rollback or fork of these bytes gives, restored here.
  World local{WorldSettings{}};
  const bool decodes = framing.empty() && restore_encoded(&local, sent).ok();
  const uint64_t into = messages.empty() || !messages[0].has_chunk() ? 0 : messages[0].world_id();
  const bool known_target = into == 0 || into == world;

  for (const v1::RestoreSnapshotChunk& m : messages) fuzz::print(m);
  auto ctx = context();
  v1::RestoreSnapshotReply reply;
  {
    auto writer = h->stub->RestoreSnapshotStream(ctx.get(), &reply);
    for (const v1::RestoreSnapshotChunk& m : messages) {
      if (!writer->Write(m)) break;
    }
    writer->WritesDone();
    const grpc::Status s = writer->Finish();
    if (std::getenv("FULCRUM_FUZZ_PRINT") != nullptr) {
      std::fprintf(stderr, "-> %s (the rules: %s)\n", s.ok() ? "OK" : s.error_message().c_str(),
                   framing.empty() ? "sound" : framing.c_str());
    }
    const auto after = fuzz::worlds(registry);
    if (!s.ok()) {
      const std::string& message = s.error_message();
      fuzz::check(message.rfind("chunks", 0) == 0 || message.rfind("snapshot", 0) == 0 ||
                      message.rfind("world_id", 0) == 0,
                  "a refusal that names no field: " + message);
      fuzz::check(after == before, "a refused upload changed a world: " + message);
      fuzz::check(!framing.empty() || damaged || !known_target,
                  "a sound upload of the snapshot was refused: " + message);
    } else {
      fuzz::check(framing.empty(),
                  "an upload the framing rules refuse (" + framing + ") was accepted");
      fuzz::check(decodes, "bytes that do not restore here were restored");
      fuzz::check(reply.tick() == local.tick() && reply.state_hash() == local.state_hash(),
                  "the upload restored another world than its bytes hold");
      if (!damaged) {
        const auto& state = h->payload_states[source];
        fuzz::check(reply.tick() == state.first && reply.state_hash() == state.second,
                    "the upload restored another world than the snapshot it carried");
      }
      fuzz::check(
          (into != 0 ? reply.world_id() == world : before.count(reply.world_id()) == 0) &&
              after.count(reply.world_id()) == 1 &&
              after.at(reply.world_id()) == std::make_pair(local.tick(), local.state_hash()),
          "the world restored is not the one the reply names, at its tick and hash");
      for (const auto& [id, state] : before) {
        if (id != reply.world_id()) {
          fuzz::check(after.at(id) == state, "an upload changed a world it did not name");
        }
      }
      fuzz::check_world(local, "the restored world");
      if ((setup & 8) != 0) check_download(*h, reply.world_id(), after.at(reply.world_id()));
    }
  }
  for (const auto& session : registry.list()) (void)registry.remove(session->id());
  return 0;
}
