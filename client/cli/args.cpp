#include "args.h"

#include <algorithm>
#include <cctype>
#include <charconv>
#include <limits>

namespace fulcrum::cli {
namespace {

const FlagSpec* find_spec(std::span<const FlagSpec> specs, std::string_view name) {
  for (const FlagSpec& spec : specs) {
    if (spec.name == name) return &spec;
  }
  return nullptr;
}

}  // namespace

bool Args::parse(std::span<const std::string> argv, std::span<const FlagSpec> specs, Args* out,
                 std::string* error) {
  *out = Args();
  bool flags_done = false;
  for (size_t i = 0; i < argv.size(); ++i) {
    const std::string& word = argv[i];
    // A negative number ("-5", "-.5") is a positional argument, not a flag.
    const bool negative_number =
        word.size() >= 2 && word[0] == '-' &&
        (std::isdigit(static_cast<unsigned char>(word[1])) || word[1] == '.');
    if (flags_done || word.size() < 2 || word[0] != '-' || negative_number) {
      out->positional_.push_back(word);
      continue;
    }
    if (word == "--") {
      flags_done = true;
      continue;
    }
    if (word == "-h" || word == "--help") {
      out->help_ = true;
      continue;
    }
    if (word.rfind("--", 0) != 0) {
      *error = "unknown flag '" + word + "' (flags are spelt --name)";
      return false;
    }
    std::string name = word.substr(2);
    std::optional<std::string> inline_value;
    if (size_t eq = name.find('='); eq != std::string::npos) {
      inline_value = name.substr(eq + 1);
      name.resize(eq);
    }
    const FlagSpec* spec = find_spec(specs, name);
    if (spec == nullptr) {
      *error = "unknown flag '--" + name + "'";
      return false;
    }
    if (out->values_.count(name) != 0 && !spec->repeatable) {
      *error = "--" + name + " given more than once";
      return false;
    }
    std::string value;
    if (spec->value_name.empty()) {
      if (inline_value) {
        *error = "--" + name + " takes no value";
        return false;
      }
    } else if (inline_value) {
      value = *inline_value;
    } else {
      // A following flag is not taken as the value: "--scene --ticks 5" is a missing value.
      if (i + 1 >= argv.size() || argv[i + 1].rfind("--", 0) == 0) {
        if (!spec->value_optional) {
          *error = "--" + name + " needs a value (" + std::string(spec->value_name) + ")";
          return false;
        }
      } else {
        value = argv[++i];
      }
    }
    out->values_[name].push_back(std::move(value));
  }
  return true;
}

std::optional<std::string> Args::value(std::string_view name) const {
  auto it = values_.find(std::string(name));
  if (it == values_.end()) return std::nullopt;
  return it->second.front();
}

std::vector<std::string> Args::values(std::string_view name) const {
  auto it = values_.find(std::string(name));
  return it == values_.end() ? std::vector<std::string>() : it->second;
}

std::optional<int64_t> parse_int(std::string_view text, int64_t min, int64_t max,
                                 std::string* error) {
  int64_t value = 0;
  const char* begin = text.data();
  const char* end = text.data() + text.size();
  auto [ptr, ec] = std::from_chars(begin, end, value);
  if (text.empty() || ec == std::errc::invalid_argument || ptr != end) {
    *error = "expected a whole number, got '" + std::string(text) + "'";
    return std::nullopt;
  }
  if (ec == std::errc::result_out_of_range) {
    *error = "number out of range: " + std::string(text);
    return std::nullopt;
  }
  if (value < min || value > max) {
    *error = "must be ";
    if (max == std::numeric_limits<int64_t>::max()) {
      *error += ">= " + std::to_string(min);
    } else {
      *error += "in [" + std::to_string(min) + ", " + std::to_string(max) + "]";
    }
    *error += ", got " + std::string(text);
    return std::nullopt;
  }
  return value;
}

std::optional<std::vector<BodyId>> parse_body_list(const std::string& text, std::string* error) {
  std::vector<BodyId> out;
  size_t start = 0;
  while (start <= text.size()) {
    const size_t comma = std::min(text.find(',', start), text.size());
    const std::string item = text.substr(start, comma - start);
    const size_t colon = item.find(':');
    std::optional<int64_t> index = parse_int(item.substr(0, colon), 0, 0x7fffffff, error);
    if (!index) {
      *error = "'" + item + "': " + *error;
      return std::nullopt;
    }
    int64_t generation = 1;
    if (colon != std::string::npos) {
      std::optional<int64_t> g = parse_int(item.substr(colon + 1), 1, 0xffffffffLL, error);
      if (!g) {
        *error = "'" + item + "': generation: " + *error;
        return std::nullopt;
      }
      generation = *g;
    }
    out.push_back(BodyId{static_cast<int32_t>(*index), static_cast<uint32_t>(generation)});
    start = comma + 1;
  }
  return out;
}

}  // namespace fulcrum::cli
