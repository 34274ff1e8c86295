// DownloadReplay: one callback reactor per call that sends a replay file in chunks of at most
// 64 KiB, reading the next chunk only when the previous one is written, so a slow reader costs
// the server one chunk of memory.
#pragma once

#include <grpcpp/grpcpp.h>

#include "fulcrum/v1/runtime.pb.h"
#include "recorder.h"

namespace fulcrum::server {

inline constexpr size_t kReplayChunkBytes = 64 * 1024;

// Sends the first `file.bytes` bytes of `file.path` (a growing recording is sent up to its
// last complete tick as of the call). The reactor deletes itself when done.
grpc::ServerWriteReactor<v1::ReplayChunk>* start_replay_download(const ReplayFileRef& file);

}  // namespace fulcrum::server
