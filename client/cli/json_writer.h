// A minimal JSON object writer for the CLI's --json output: one object on one line, keys in
// the order written, doubles in the shortest form that parses back to the same bits.
#pragma once

#include <charconv>
#include <cmath>
#include <cstdint>
#include <ostream>
#include <string>
#include <string_view>

namespace fulcrum::cli {

class JsonWriter {
 public:
  explicit JsonWriter(std::ostream& out) : out_(out) { out_ << "{"; }

  void field(std::string_view key, std::string_view value) {
    write_key(key);
    write_string(value);
  }
  void field(std::string_view key, const char* value) { field(key, std::string_view(value)); }
  void field(std::string_view key, double value) {
    write_key(key);
    // JSON has no NaN or infinity.
    if (!std::isfinite(value)) {
      out_ << "null";
      return;
    }
    char buf[64];
    auto [end, ec] = std::to_chars(buf, buf + sizeof(buf), value);
    out_ << std::string_view(buf, ec == std::errc() ? end - buf : 0);
  }
  void field(std::string_view key, int64_t value) {
    write_key(key);
    out_ << value;
  }
  void field(std::string_view key, int value) { field(key, static_cast<int64_t>(value)); }
  void field(std::string_view key, bool value) {
    write_key(key);
    out_ << (value ? "true" : "false");
  }
  void null_field(std::string_view key) {
    write_key(key);
    out_ << "null";
  }
  // A nested object: begin_object(key), fields, end_object().
  void begin_object(std::string_view key) {
    write_key(key);
    out_ << "{";
    first_ = true;
  }
  void end_object() {
    out_ << "}";
    first_ = false;
  }
  // Closes the top-level object and ends the line.
  void finish() { out_ << "}\n"; }

 private:
  void write_key(std::string_view key) {
    if (!first_) out_ << ",";
    first_ = false;
    write_string(key);
    out_ << ":";
  }
  void write_string(std::string_view s) {
    out_ << '"';
    for (char ch : s) {
      const auto c = static_cast<unsigned char>(ch);
      if (c == '"' || c == '\\') {
        out_ << '\\' << ch;
      } else if (c < 0x20) {
        static constexpr char kHex[] = "0123456789abcdef";
        out_ << "\\u00" << kHex[c >> 4] << kHex[c & 15];
      } else {
        out_ << ch;
      }
    }
    out_ << '"';
  }

  std::ostream& out_;
  bool first_ = true;
};

}  // namespace fulcrum::cli
