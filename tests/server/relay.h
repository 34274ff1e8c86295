// A loopback TCP relay for the session tests: a stand-in for a slow, jittery network between one
// client and fulcrum-server. It listens on 127.0.0.1 (an ephemeral port), and for each
// connection it accepts it opens one to the target and forwards bytes both ways. Each chunk of
// bytes read is held for a random 0 to max_delay ms, drawn from a generator seeded per relay,
// connection and direction, before it is written on. A chunk is never written before the chunk
// read ahead of it on the same connection and direction (the byte order of TCP is kept), so a
// chunk drawn a short delay behind a long one waits for it; but two relays' connections are
// independent, so different players' traffic reaches the server out of order relative to each
// other.
//
// Threads, not an event loop: one accepting, and per connection and direction one reading and
// one writing (the writer sleeps until the head chunk is due). A test opens a few connections,
// so a few dozen mostly sleeping threads are simpler than a poller and cost nothing that shows.
#pragma once

#include <arpa/inet.h>
#include <netinet/in.h>
#include <netinet/tcp.h>
#include <sys/socket.h>
#include <unistd.h>

#include <algorithm>
#include <atomic>
#include <chrono>
#include <condition_variable>
#include <cstdint>
#include <cstdlib>
#include <deque>
#include <memory>
#include <mutex>
#include <random>
#include <string>
#include <thread>
#include <vector>

namespace fulcrum::testing_support {

class Relay {
 public:
  using Clock = std::chrono::steady_clock;

  // Forwards to `target_port` on 127.0.0.1. address() is empty when the relay could not listen.
  Relay(int target_port, uint64_t seed, std::chrono::milliseconds max_delay)
      : target_port_(target_port), seed_(seed), max_delay_(max_delay) {
    listen_fd_ = socket(AF_INET, SOCK_STREAM, 0);
    sockaddr_in at{};
    at.sin_family = AF_INET;
    at.sin_addr.s_addr = htonl(INADDR_LOOPBACK);
    at.sin_port = 0;
    socklen_t size = sizeof(at);
    if (listen_fd_ < 0 || bind(listen_fd_, reinterpret_cast<sockaddr*>(&at), sizeof(at)) != 0 ||
        listen(listen_fd_, 16) != 0 ||
        getsockname(listen_fd_, reinterpret_cast<sockaddr*>(&at), &size) != 0) {
      return;
    }
    address_ = "127.0.0.1:" + std::to_string(ntohs(at.sin_port));
    acceptor_ = std::thread([this] { accept_loop(); });
  }

  // "127.0.0.1:PORT" of fulcrum-server's "listening on" line, or a bare port.
  static int port_of(const std::string& address) {
    const size_t colon = address.rfind(':');
    return std::atoi(address.c_str() + (colon == std::string::npos ? 0 : colon + 1));
  }

  Relay(const Relay&) = delete;
  Relay& operator=(const Relay&) = delete;

  ~Relay() {
    stopping_ = true;
    if (listen_fd_ >= 0) shutdown(listen_fd_, SHUT_RDWR);  // wakes accept()
    if (acceptor_.joinable()) acceptor_.join();
    if (listen_fd_ >= 0) close(listen_fd_);
    std::vector<std::unique_ptr<Connection>> connections;
    {
      std::lock_guard<std::mutex> lock(mu_);
      connections.swap(connections_);
    }
    for (auto& c : connections) c->stop();
  }

  const std::string& address() const { return address_; }
  int64_t connections() const { return connection_count_; }
  int64_t chunks() const { return chunks_; }
  int64_t bytes() const { return bytes_; }

 private:
  // One chunk of bytes read, and when it may be written.
  struct Chunk {
    std::string bytes;  // empty: the reader saw the end of the stream
    Clock::time_point due;
  };

  // One direction of one connection: `from` is read, `to` written.
  struct Pipe {
    Relay* relay = nullptr;
    int from = -1;
    int to = -1;
    std::mt19937_64 random;
    std::mutex mu;
    std::condition_variable cv;
    std::deque<Chunk> queue;
    bool stopped = false;
    std::thread reader;
    std::thread writer;

    void read_loop() {
      std::string buffer(64 * 1024, '\0');
      Clock::time_point last_due = Clock::now();
      for (;;) {
        const ssize_t n = recv(from, buffer.data(), buffer.size(), 0);
        Chunk chunk;
        // A draw per chunk; never before the chunk ahead of it, which keeps the byte order.
        const auto delay = std::chrono::milliseconds(
            static_cast<int64_t>(random() % static_cast<uint64_t>(relay->max_delay_.count() + 1)));
        chunk.due = std::max(Clock::now() + delay, last_due);
        last_due = chunk.due;
        if (n > 0) chunk.bytes.assign(buffer.data(), static_cast<size_t>(n));
        {
          std::lock_guard<std::mutex> lock(mu);
          queue.push_back(std::move(chunk));
        }
        cv.notify_all();
        if (n <= 0) return;
        ++relay->chunks_;
        relay->bytes_ += n;
      }
    }

    void write_loop() {
      for (;;) {
        Chunk chunk;
        {
          std::unique_lock<std::mutex> lock(mu);
          cv.wait(lock, [&] { return stopped || !queue.empty(); });
          if (stopped) return;
          const Clock::time_point due = queue.front().due;
          if (cv.wait_until(lock, due, [&] { return stopped; })) return;
          chunk = std::move(queue.front());
          queue.pop_front();
        }
        if (chunk.bytes.empty()) {  // the end of the stream, in its place in the byte order
          shutdown(to, SHUT_WR);
          return;
        }
        for (size_t sent = 0; sent < chunk.bytes.size();) {
          const ssize_t n =
              send(to, chunk.bytes.data() + sent, chunk.bytes.size() - sent, MSG_NOSIGNAL);
          if (n <= 0) {
            shutdown(from, SHUT_RDWR);  // the other end is gone: end the reader too
            return;
          }
          sent += static_cast<size_t>(n);
        }
      }
    }

    void start() {
      reader = std::thread([this] { read_loop(); });
      writer = std::thread([this] { write_loop(); });
    }
    void stop() {
      {
        std::lock_guard<std::mutex> lock(mu);
        stopped = true;
      }
      cv.notify_all();
    }
    void join() {
      if (reader.joinable()) reader.join();
      if (writer.joinable()) writer.join();
    }
  };

  struct Connection {
    int client = -1;
    int server = -1;
    Pipe up;    // client to server
    Pipe down;  // server to client

    void stop() {
      up.stop();
      down.stop();
      shutdown(client, SHUT_RDWR);  // wakes both readers
      shutdown(server, SHUT_RDWR);
      up.join();
      down.join();
      close(client);
      close(server);
    }
  };

  void accept_loop() {
    for (int index = 0;; ++index) {
      const int client = accept(listen_fd_, nullptr, nullptr);
      if (client < 0) {
        if (stopping_) return;
        continue;
      }
      const int server = socket(AF_INET, SOCK_STREAM, 0);
      sockaddr_in at{};
      at.sin_family = AF_INET;
      at.sin_addr.s_addr = htonl(INADDR_LOOPBACK);
      at.sin_port = htons(static_cast<uint16_t>(target_port_));
      if (server < 0 || connect(server, reinterpret_cast<sockaddr*>(&at), sizeof(at)) != 0) {
        close(client);
        if (server >= 0) close(server);
        continue;
      }
      // Without Nagle's algorithm the delays are the relay's alone.
      const int one = 1;
      setsockopt(client, IPPROTO_TCP, TCP_NODELAY, &one, sizeof(one));
      setsockopt(server, IPPROTO_TCP, TCP_NODELAY, &one, sizeof(one));
      auto c = std::make_unique<Connection>();
      c->client = client;
      c->server = server;
      c->up.relay = c->down.relay = this;
      c->up.from = c->down.to = client;
      c->up.to = c->down.from = server;
      // One seed per relay, connection and direction.
      c->up.random.seed(seed_ * 1000003ULL + static_cast<uint64_t>(index) * 2);
      c->down.random.seed(seed_ * 1000003ULL + static_cast<uint64_t>(index) * 2 + 1);
      c->up.start();
      c->down.start();
      ++connection_count_;
      std::lock_guard<std::mutex> lock(mu_);
      connections_.push_back(std::move(c));
    }
  }

  const int target_port_;
  const uint64_t seed_;
  const std::chrono::milliseconds max_delay_;
  int listen_fd_ = -1;
  std::string address_;
  std::atomic<bool> stopping_{false};
  std::atomic<int64_t> connection_count_{0};
  std::atomic<int64_t> chunks_{0};
  std::atomic<int64_t> bytes_{0};
  std::thread acceptor_;
  std::mutex mu_;
  std::vector<std::unique_ptr<Connection>> connections_;
};

}  // namespace fulcrum::testing_support
