#include "replay_download.h"

#include <algorithm>
#include <fstream>
#include <string>

namespace fulcrum::server {

namespace {

class ReplayDownload final : public grpc::ServerWriteReactor<v1::ReplayChunk> {
 public:
  explicit ReplayDownload(const ReplayFileRef& file)
      : file_(file), in_(file.path, std::ios::binary) {
    if (!in_) {
      Finish(grpc::Status(grpc::StatusCode::NOT_FOUND,
                          "name: replay " + file.name + " cannot be opened"));
      return;
    }
    send_next(true);
  }

  void OnWriteDone(bool ok) override {
    if (!ok) {
      Finish(grpc::Status(grpc::StatusCode::CANCELLED, "the download was broken off"));
      return;
    }
    if (sent_ == file_.bytes && done_) {
      Finish(grpc::Status::OK);
      return;
    }
    send_next(false);
  }

  void OnDone() override { delete this; }

 private:
  void send_next(bool first) {
    const size_t n =
        static_cast<size_t>(std::min<uint64_t>(kReplayChunkBytes, file_.bytes - sent_));
    message_.Clear();
    if (first) {
      message_.set_name(file_.name);
      message_.set_total_size(file_.bytes);
    }
    message_.set_offset(sent_);
    std::string* data = message_.mutable_data();
    data->resize(n);
    if (n > 0 && !in_.read(data->data(), static_cast<std::streamsize>(n))) {
      Finish(grpc::Status(grpc::StatusCode::DATA_LOSS,
                          "replay " + file_.name + " is shorter than " +
                              std::to_string(file_.bytes) + " bytes (changed on disk?)"));
      return;
    }
    checksum_.update(*data);
    sent_ += n;
    if (sent_ == file_.bytes) {
      message_.set_last(true);
      message_.set_checksum(checksum_.value());
      done_ = true;
    }
    StartWrite(&message_);
  }

  // FNV-1a 64 over the bytes sent, chunk by chunk (the same sum as fnv1a64 over the file).
  struct Fnv1a64 {
    uint64_t h = 0xcbf29ce484222325ULL;
    void update(const std::string& bytes) {
      for (char c : bytes) {
        h ^= static_cast<unsigned char>(c);
        h *= 0x100000001b3ULL;
      }
    }
    uint64_t value() const { return h; }
  };

  const ReplayFileRef file_;
  std::ifstream in_;
  v1::ReplayChunk message_;
  uint64_t sent_ = 0;
  bool done_ = false;
  Fnv1a64 checksum_;
};

}  // namespace

grpc::ServerWriteReactor<v1::ReplayChunk>* start_replay_download(const ReplayFileRef& file) {
  return new ReplayDownload(file);
}

}  // namespace fulcrum::server
