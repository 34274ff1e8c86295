// What the server tests share: the example pyramid scene as JSON, and polling for a condition.
#pragma once

#include <chrono>
#include <fstream>
#include <functional>
#include <sstream>
#include <string>
#include <thread>

namespace fulcrum::testing_support {

inline std::string read_text(const std::string& path) {
  std::ifstream in(path);
  std::ostringstream s;
  s << in.rdbuf();
  return s.str();
}

// scenes/pyramid.json (the tests' CMake defines FULCRUM_SCENES_DIR).
inline const std::string& pyramid_json() {
  static const std::string json = read_text(FULCRUM_SCENES_DIR "/pyramid.json");
  return json;
}

// Polls `done` every 10 ms for up to `limit`; true when it became true.
inline bool eventually(const std::function<bool()>& done,
                       std::chrono::milliseconds limit = std::chrono::seconds(20)) {
  const auto deadline = std::chrono::steady_clock::now() + limit;
  while (!done()) {
    if (std::chrono::steady_clock::now() > deadline) return false;
    std::this_thread::sleep_for(std::chrono::milliseconds(10));
  }
  return true;
}

}  // namespace fulcrum::testing_support
