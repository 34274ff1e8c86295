#include "remote.h"

#include <cinttypes>
#include <cstdio>
#include <fstream>
#include <limits>
#include <sstream>

namespace fulcrum::cli {

std::optional<std::string> read_file(const std::string& path, std::string* error) {
  std::ifstream in(path, std::ios::binary);
  if (!in) {
    *error = path + ": cannot open";
    return std::nullopt;
  }
  std::ostringstream text;
  text << in.rdbuf();
  return text.str();
}

std::unique_ptr<client::Client> connect_from_args(const Invocation& inv, int* exit_code) {
  client::ClientOptions options;
  if (auto server = inv.args.value("server")) options.address = *server;
  if (auto file = inv.args.value("token-file")) {
    std::string error;
    std::optional<std::string> text = read_file(*file, &error);
    if (!text) {
      *exit_code = inv.fail(error);
      return nullptr;
    }
    options.token = text->substr(0, text->find_first_of("\r\n"));
  }
  if (auto ms = inv.args.value("deadline-ms")) {
    std::string error;
    std::optional<int64_t> parsed = parse_int(*ms, 1, int64_t{1} << 40, &error);
    if (!parsed) {
      *exit_code = inv.usage_error("--deadline-ms: " + error);
      return nullptr;
    }
    options.deadline = std::chrono::milliseconds(*parsed);
  }
  if (auto file = inv.args.value("tls-ca")) {
    std::string error;
    std::optional<std::string> pem = read_file(*file, &error);
    if (!pem) {
      *exit_code = inv.fail("--tls-ca: " + error);
      return nullptr;
    }
    if (pem->find("-----BEGIN CERTIFICATE-----") == std::string::npos) {
      *exit_code = inv.fail("--tls-ca: " + *file + " holds no PEM certificate");
      return nullptr;
    }
    options.tls = true;
    options.tls_ca_pem = *pem;
  }
  if (auto name = inv.args.value("tls-name")) {
    if (!options.tls) {
      *exit_code = inv.usage_error("--tls-name needs --tls-ca");
      return nullptr;
    }
    options.tls_target_name = *name;
  }
  return client::Client::connect(options);
}

std::optional<uint64_t> world_arg(const Invocation& inv, size_t index, int* exit_code) {
  const auto& positional = inv.args.positional();
  if (positional.size() <= index) {
    *exit_code = inv.usage_error("missing WORLD (a world id; see `fulcrum worlds`)");
    return std::nullopt;
  }
  std::string error;
  std::optional<int64_t> id =
      parse_int(positional[index], 1, std::numeric_limits<int64_t>::max(), &error);
  if (!id) {
    *exit_code = inv.usage_error("WORLD: " + error);
    return std::nullopt;
  }
  return static_cast<uint64_t>(*id);
}

}  // namespace fulcrum::cli
