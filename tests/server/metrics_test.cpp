// fulcrum-server's Prometheus endpoint (--metrics-listen, metrics.h) scraped over HTTP as
// Prometheus does: every line is in the text exposition format (each family's HELP and TYPE
// before its samples, names and labels well formed, values numbers), and the values are the
// ones GetStats and GetWorld answer.
#include <gtest/gtest.h>

#include <chrono>
#include <map>
#include <regex>
#include <set>
#include <sstream>
#include <string>
#include <thread>

#include "fulcrum/client.h"
#include "server.h"
#include "test_support.h"

// Last: httplib.h brings <resolv.h>, whose macro _res breaks Eigen's headers included after it.
#include <httplib.h>  // NOLINT(llvm-include-order)

namespace fulcrum {
namespace {

using server::Server;
using server::ServerOptions;
using testing_support::pyramid_json;

struct Scrape {
  std::map<std::string, double> samples;  // "name{labels}" -> value
  std::map<std::string, std::string> types;
};

// Parses the exposition text, failing the test on the first line that breaks the format.
Scrape parse(const std::string& text) {
  static const std::regex help(R"(^# HELP ([a-zA-Z_:][a-zA-Z0-9_:]*) \S.*$)");
  static const std::regex type(R"(^# TYPE ([a-zA-Z_:][a-zA-Z0-9_:]*) (counter|gauge|histogram)$)");
  static const std::regex sample(
      R"(^([a-zA-Z_:][a-zA-Z0-9_:]*)(\{([a-zA-Z_][a-zA-Z0-9_]*="([^"\\\n]|\\[\\"n])*",?)*\})? )"
      R"((-?[0-9.e+-]+|\+Inf|-Inf|NaN)$)");
  Scrape out;
  std::set<std::string> helped;
  std::istringstream in(text);
  std::string line;
  std::smatch m;
  while (std::getline(in, line)) {
    if (std::regex_match(line, m, help)) {
      helped.insert(m[1]);
    } else if (std::regex_match(line, m, type)) {
      EXPECT_TRUE(helped.count(m[1])) << "TYPE before HELP: " << line;
      EXPECT_EQ(out.types.count(m[1]), 0u) << "a family twice: " << line;
      out.types[m[1]] = m[2];
    } else if (std::regex_match(line, m, sample)) {
      std::string family = m[1];
      for (const char* suffix : {"_bucket", "_sum", "_count"}) {
        const std::string base = family.substr(0, family.size() - std::strlen(suffix));
        if (family.size() > std::strlen(suffix) && family.ends_with(suffix) &&
            out.types.count(base) && out.types[base] == "histogram") {
          family = base;
        }
      }
      EXPECT_TRUE(out.types.count(family)) << "a sample before its TYPE: " << line;
      const std::string key = line.substr(0, line.rfind(' '));
      EXPECT_EQ(out.samples.count(key), 0u) << "a sample twice: " << line;
      out.samples[key] = std::stod(line.substr(line.rfind(' ') + 1));
    } else {
      ADD_FAILURE() << "not in the exposition format: '" << line << "'";
    }
  }
  return out;
}

TEST(MetricsTest, ScrapesMatchGetStatsAndGetWorld) {
  ServerOptions options;
  options.listen = "127.0.0.1:0";
  options.metrics_listen = "127.0.0.1:0";
  auto started = Server::start(options);
  ASSERT_TRUE(started.ok()) << started.status().message();
  std::unique_ptr<Server> server = std::move(started).value();
  ASSERT_FALSE(server->metrics_address().empty());
  client::ClientOptions copts;
  copts.address = server->address();
  auto client = client::Client::connect(copts);

  Result<client::WorldSummary> a = client->create_world_json(pyramid_json());
  ASSERT_TRUE(a.ok());
  Result<client::WorldSummary> b =
      client->create_world_json(R"({"name": "two \"quoted\" words", "builtin": "bounce"})");
  ASSERT_TRUE(b.ok()) << b.status().message();
  // A heavy chain's island runs 7 substeps (its budget: docs/solver.md).
  Result<client::WorldSummary> c =
      client->create_world_json(R"({"name": "chain", "builtin": "heavy_chain"})");
  ASSERT_TRUE(c.ok()) << c.status().message();
  ASSERT_TRUE(client->step(a->id, 30).ok());
  ASSERT_TRUE(client->step(b->id, 7).ok());
  ASSERT_TRUE(client->step(c->id, 1).ok());
  EXPECT_FALSE(client->step(a->id, 0).ok());   // INVALID_ARGUMENT
  EXPECT_FALSE(client->get_world(999).ok());   // NOT_FOUND
  EXPECT_FALSE(client->get_world(1000).ok());  // NOT_FOUND

  const std::string addr = server->metrics_address();
  httplib::Client http(addr.substr(0, addr.rfind(':')),
                       std::stoi(addr.substr(addr.rfind(':') + 1)));
  httplib::Result res = http.Get("/metrics");
  ASSERT_TRUE(res) << "no answer from " << addr;
  EXPECT_EQ(res->status, 200);
  EXPECT_EQ(res->get_header_value("Content-Type"), "text/plain; version=0.0.4; charset=utf-8");
  const Scrape scrape = parse(res->body);
  Result<v1::ServerStats> stats = client->get_stats();
  ASSERT_TRUE(stats.ok());

  // Counters the calls above moved, equal to GetStats (nothing else runs in this process).
  const auto& s = scrape.samples;
  EXPECT_EQ(s.at("fulcrum_worlds"), 3);
  EXPECT_EQ(s.at("fulcrum_worlds_created_total"), stats->worlds_created());
  EXPECT_EQ(s.at("fulcrum_ticks_total"), stats->ticks_stepped());
  EXPECT_GE(s.at("fulcrum_ticks_total"), 38);
  EXPECT_EQ(s.at("fulcrum_refused_total{code=\"NOT_FOUND\"}"), 2);
  EXPECT_EQ(s.at("fulcrum_refused_total{code=\"INVALID_ARGUMENT\"}"), 1);
  EXPECT_EQ(s.at("fulcrum_refused_total{code=\"DATA_LOSS\"}"), 0);
  // The histogram: cumulative buckets ending in +Inf, which counts every tick.
  EXPECT_EQ(scrape.types.at("fulcrum_step_seconds"), "histogram");
  EXPECT_EQ(s.at("fulcrum_step_seconds_bucket{le=\"+Inf\"}"), s.at("fulcrum_ticks_total"));
  EXPECT_EQ(s.at("fulcrum_step_seconds_count"), s.at("fulcrum_ticks_total"));
  EXPECT_LE(s.at("fulcrum_step_seconds_bucket{le=\"0.001\"}"),
            s.at("fulcrum_step_seconds_bucket{le=\"0.01\"}"));
  EXPECT_NEAR(s.at("fulcrum_step_seconds_sum"), stats->step_ms_total() * 1e-3, 1e-9);
  // Per world, labelled by id and name (quotes escaped).
  const std::string la = "{world=\"" + std::to_string(a->id) + "\",name=\"pyramid\"}";
  const std::string lb =
      "{world=\"" + std::to_string(b->id) + "\",name=\"two \\\"quoted\\\" words\"}";
  EXPECT_EQ(s.at("fulcrum_world_tick" + la), 30);
  EXPECT_EQ(s.at("fulcrum_world_tick" + lb), 7);
  Result<client::WorldSummary> info = client->get_world(a->id);
  ASSERT_TRUE(info.ok());
  EXPECT_EQ(s.at("fulcrum_world_bodies" + la), info->body_count);
  EXPECT_EQ(s.at("fulcrum_world_real_time" + la), 0);
  // Budgets: the pyramid needs none, the heavy chain's one island runs 7 substeps.
  const std::string lc = "{world=\"" + std::to_string(c->id) + "\",name=\"chain\"}";
  EXPECT_EQ(s.at("fulcrum_world_budget_islands" + la), 0);
  EXPECT_EQ(s.at("fulcrum_world_max_substeps" + la), 4);
  EXPECT_EQ(s.at("fulcrum_world_budget_islands" + lc), 1);
  EXPECT_EQ(s.at("fulcrum_world_max_substeps" + lc), 7);

  // Another path is not found; a second scrape sees the server move on.
  EXPECT_EQ(http.Get("/")->status, 404);
  ASSERT_TRUE(client->set_run_mode(b->id, client::RunMode::kRealTime).ok());
  std::this_thread::sleep_for(std::chrono::milliseconds(200));
  const Scrape later = parse(http.Get("/metrics")->body);
  EXPECT_EQ(later.samples.at("fulcrum_world_real_time" + lb), 1);
  EXPECT_GT(later.samples.at("fulcrum_world_tick" + lb), 7);
  EXPECT_GT(later.samples.at("fulcrum_ticks_total"), s.at("fulcrum_ticks_total"));
  server->shutdown(std::chrono::milliseconds(0));
  EXPECT_FALSE(http.Get("/metrics")) << "the endpoint closes with the server";
}

TEST(MetricsTest, ABadOrBusyAddressIsRefusedAtStart) {
  ServerOptions options;
  options.listen = "127.0.0.1:0";
  options.metrics_listen = "localhost";
  auto bad = Server::start(options);
  ASSERT_FALSE(bad.ok());
  EXPECT_EQ(bad.status().message(), "metrics_listen: expected HOST:PORT (got 'localhost')");
  options.metrics_listen = "127.0.0.1:0";
  auto first = Server::start(options);
  ASSERT_TRUE(first.ok());
  options.metrics_listen = (*first)->metrics_address();
  auto busy = Server::start(options);
  ASSERT_FALSE(busy.ok());
  EXPECT_EQ(busy.status().code(), StatusCode::kUnavailable);
  EXPECT_NE(busy.status().message().find("cannot listen on " + options.metrics_listen),
            std::string::npos)
      << busy.status().message();
}

}  // namespace
}  // namespace fulcrum
