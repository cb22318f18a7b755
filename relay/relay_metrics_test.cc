// Starts a real MetricsExporter on an ephemeral port and scrapes it over HTTP with libcurl.
#include "metrics/metrics_exporter.h"
#include "relay/relay_metrics.h"

#include <curl/curl.h>
#include <gmock/gmock.h>
#include <gtest/gtest.h>
#include <sys/wait.h>
#include <unistd.h>

#include <cstdint>
#include <cstdio>
#include <ctime>
#include <cstdlib>
#include <fstream>
#include <map>
#include <memory>
#include <set>
#include <sstream>
#include <string>
#include <vector>

#include "protocol/connection.h"
#include "protocol/packet.h"

namespace edgephys {
namespace {

using ::testing::HasSubstr;
using ::testing::Not;

struct HttpResponse {
  bool ok = false;  // transfer completed (any HTTP status)
  long status = 0;
  std::string body;
  std::string error;
};

size_t AppendBody(char* data, size_t size, size_t nmemb, void* user) {
  static_cast<std::string*>(user)->append(data, size * nmemb);
  return size * nmemb;
}

HttpResponse HttpGet(const std::string& url) {
  HttpResponse response;
  CURL* curl = curl_easy_init();
  if (curl == nullptr) {
    response.error = "curl_easy_init failed";
    return response;
  }
  curl_easy_setopt(curl, CURLOPT_URL, url.c_str());
  curl_easy_setopt(curl, CURLOPT_WRITEFUNCTION, &AppendBody);
  curl_easy_setopt(curl, CURLOPT_WRITEDATA, &response.body);
  curl_easy_setopt(curl, CURLOPT_TIMEOUT, 10L);
  curl_easy_setopt(curl, CURLOPT_NOSIGNAL, 1L);
  const CURLcode rc = curl_easy_perform(curl);
  if (rc == CURLE_OK) {
    response.ok = true;
    curl_easy_getinfo(curl, CURLINFO_RESPONSE_CODE, &response.status);
  } else {
    response.error = curl_easy_strerror(rc);
  }
  curl_easy_cleanup(curl);
  return response;
}

std::string MetricsUrl(const MetricsExporter& exporter) {
  return "http://127.0.0.1:" + std::to_string(exporter.port()) + "/metrics";
}

// Scrapes and asserts HTTP 200; returns the exposition text.
std::string Scrape(const MetricsExporter& exporter) {
  HttpResponse r = HttpGet(MetricsUrl(exporter));
  EXPECT_TRUE(r.ok) << r.error;
  EXPECT_EQ(r.status, 200);
  return r.body;
}

// Sample lines keyed by "name{labels}" exactly as exposed; value parsed as double.
std::map<std::string, double> ParseSamples(const std::string& text) {
  std::map<std::string, double> samples;
  std::istringstream in(text);
  std::string line;
  while (std::getline(in, line)) {
    if (line.empty() || line[0] == '#') continue;
    const size_t space = line.rfind(' ');
    if (space == std::string::npos) continue;
    samples[line.substr(0, space)] = std::stod(line.substr(space + 1));
  }
  return samples;
}

// Expects every series of `expected` among `samples` (parsed from `text`) with its value; a
// missing series fails fatally, naming it and showing `text`.
void ExpectSamples(const std::map<std::string, double>& samples,
                   const std::map<std::string, double>& expected, const std::string& text) {
  for (const auto& [series, value] : expected) {
    auto it = samples.find(series);
    ASSERT_NE(it, samples.end()) << series << " missing from:\n" << text;
    EXPECT_EQ(it->second, value) << series;
  }
}

class MetricsExporterTest : public ::testing::Test {
 protected:
  static void SetUpTestSuite() { curl_global_init(CURL_GLOBAL_DEFAULT); }
  static void TearDownTestSuite() { curl_global_cleanup(); }

  void SetUp() override {
    auto started = MetricsExporter::Start("127.0.0.1:0", RelayMetrics(&counters_));
    ASSERT_TRUE(started.ok()) << started.status().message();
    exporter_ = std::move(started.value());
    ASSERT_NE(exporter_->port(), 0);
  }

  RelayCounters counters_;
  std::unique_ptr<MetricsExporter> exporter_;
};

TEST_F(MetricsExporterTest, ExportsScalarCountersAndGauges) {
  RelayCounters::Inc(counters_.packets_received, 42);
  RelayCounters::Inc(counters_.packets_sent, 7);
  RelayCounters::Inc(counters_.bytes_received, 123456);
  RelayCounters::Inc(counters_.bytes_sent, 654321);
  RelayCounters::Inc(counters_.entity_updates_sent, 11);
  RelayCounters::Inc(counters_.entity_updates_received, 12);
  RelayCounters::Inc(counters_.reliable_resends, 3);
  RelayCounters::Inc(counters_.reliable_messages_received, 4);
  RelayCounters::Inc(counters_.connections_accepted, 5);
  RelayCounters::Inc(counters_.send_errors, 6);
  RelayCounters::Inc(counters_.io_queue_drops, 8);
  RelayCounters::Inc(counters_.reassembly_evictions, 13);
  counters_.reassembly_held_bytes = 65536;
  counters_.rooms = 2;
  counters_.clients = 9;
  counters_.entities = 31;

  const std::string text = Scrape(*exporter_);
  EXPECT_THAT(text, HasSubstr("\nedgephys_packets_received_total 42\n"));

  const auto samples = ParseSamples(text);
  const std::map<std::string, double> expected = {
      {"edgephys_packets_received_total", 42},
      {"edgephys_packets_sent_total", 7},
      {"edgephys_bytes_received_total", 123456},
      {"edgephys_bytes_sent_total", 654321},
      {"edgephys_entity_updates_sent_total", 11},
      {"edgephys_entity_updates_received_total", 12},
      {"edgephys_reliable_resends_total", 3},
      {"edgephys_reliable_messages_received_total", 4},
      {"edgephys_connections_accepted_total", 5},
      {"edgephys_send_errors_total", 6},
      {"edgephys_io_queue_drops_total", 8},
      {"edgephys_reassembly_evictions_total", 13},
      {"edgephys_reassembly_held_bytes", 65536},
      {"edgephys_rooms", 2},
      {"edgephys_clients", 9},
      {"edgephys_entities", 31},
      {"edgephys_build_info{version=\"0.1.0\"}", 1},
  };
  ASSERT_NO_FATAL_FAILURE(ExpectSamples(samples, expected, text));
}

TEST_F(MetricsExporterTest, TypeAndHelpLinesAndSingleTotalSuffix) {
  const std::string text = Scrape(*exporter_);
  const std::vector<std::pair<std::string, std::string>> families = {
      {"edgephys_rooms", "gauge"},
      {"edgephys_clients", "gauge"},
      {"edgephys_entities", "gauge"},
      {"edgephys_build_info", "gauge"},
      {"edgephys_packets_received_total", "counter"},
      {"edgephys_packets_sent_total", "counter"},
      {"edgephys_bytes_received_total", "counter"},
      {"edgephys_bytes_sent_total", "counter"},
      {"edgephys_entity_updates_sent_total", "counter"},
      {"edgephys_entity_updates_received_total", "counter"},
      {"edgephys_reliable_resends_total", "counter"},
      {"edgephys_reliable_messages_received_total", "counter"},
      {"edgephys_connections_accepted_total", "counter"},
      {"edgephys_send_errors_total", "counter"},
      {"edgephys_io_queue_drops_total", "counter"},
      {"edgephys_reassembly_held_bytes", "gauge"},
      {"edgephys_reassembly_evictions_total", "counter"},
      {"edgephys_packets_rejected_total", "counter"},
      {"edgephys_entity_updates_rejected_total", "counter"},
      {"edgephys_requests_rejected_total", "counter"},
      {"edgephys_disconnects_total", "counter"},
      {"edgephys_rtt_seconds", "histogram"},
      {"edgephys_tick_duration_seconds", "histogram"},
      {"edgephys_cluster_redis_errors_total", "counter"},
      {"edgephys_cluster_bad_keys_total", "counter"},
      {"edgephys_cluster_redirects_total", "counter"},
      {"edgephys_cluster_rooms_restored_total", "counter"},
  };
  for (const auto& [name, type] : families) {
    EXPECT_THAT(text, HasSubstr("# TYPE " + name + " " + type + "\n")) << name;
    EXPECT_THAT(text, HasSubstr("# HELP " + name + " ")) << name;
  }
  EXPECT_THAT(text, Not(HasSubstr("_total_total")));
}

TEST_F(MetricsExporterTest, BudgetRefusalsExportedByBudget) {
  counters_.RefuseOverBudget(BudgetKind::kRoomParticles);
  counters_.RejectRequest(17);  // schema::RejectReason::OverBudget
  const auto samples = ParseSamples(Scrape(*exporter_));
  EXPECT_EQ(samples.at("edgephys_budget_refusals_total{reason=\"room_particles\"}"), 1);
  EXPECT_EQ(samples.at("edgephys_budget_refusals_total{reason=\"player_entities\"}"), 0);
  EXPECT_EQ(samples.at("edgephys_requests_rejected_total{reason=\"over_budget\"}"), 1);
}

TEST_F(MetricsExporterTest, DropReasonLabelsExportedEvenAtZero) {
  counters_.RejectPacket(DropReason::kBadCookie);
  counters_.RejectPacket(DropReason::kBadCookie);
  counters_.RejectPacket(DropReason::kTooShort);
  counters_.RejectUpdate(DropReason::kNotOwner);

  const auto samples = ParseSamples(Scrape(*exporter_));
  for (size_t i = 0; i < static_cast<size_t>(DropReason::kCount); ++i) {
    const auto reason = static_cast<DropReason>(i);
    const std::string label = "{reason=\"" + std::string(DropReasonName(reason)) + "\"}";
    ASSERT_FALSE(DropReasonName(reason).empty()) << i;
    ASSERT_TRUE(samples.contains("edgephys_packets_rejected_total" + label)) << label;
    ASSERT_TRUE(samples.contains("edgephys_entity_updates_rejected_total" + label)) << label;
    const double want_packets = reason == DropReason::kBadCookie ? 2
                                : reason == DropReason::kTooShort ? 1
                                                                   : 0;
    const double want_updates = reason == DropReason::kNotOwner ? 1 : 0;
    EXPECT_EQ(samples.at("edgephys_packets_rejected_total" + label), want_packets) << label;
    EXPECT_EQ(samples.at("edgephys_entity_updates_rejected_total" + label), want_updates)
        << label;
  }
  // One distinct series per reason: a repeated or missing DropReasonName() would collapse them.
  std::set<std::string> names;
  for (size_t i = 0; i < static_cast<size_t>(DropReason::kCount); ++i) {
    names.emplace(DropReasonName(static_cast<DropReason>(i)));
  }
  EXPECT_EQ(names.size(), static_cast<size_t>(DropReason::kCount))
      << "DropReasonName() repeats a name";
  size_t packet_series = 0;
  for (const auto& [series, value] : samples) {
    if (series.starts_with("edgephys_packets_rejected_total{")) ++packet_series;
  }
  EXPECT_EQ(packet_series, static_cast<size_t>(DropReason::kCount));
}

TEST_F(MetricsExporterTest, RejectAndDisconnectReasonsInSnakeCase) {
  counters_.RejectRequest(1);  // BadToken
  counters_.RejectRequest(1);
  counters_.RejectRequest(2);   // ExpiredToken
  counters_.RejectRequest(13);  // BadCookie
  counters_.RejectRequest(0);   // None: counted by the core, never exported
  counters_.CountDisconnect(DisconnectReason::kTimeout);
  counters_.CountDisconnect(DisconnectReason::kClientLeft);
  counters_.CountDisconnect(DisconnectReason::kClientLeft);

  const std::string text = Scrape(*exporter_);
  const auto samples = ParseSamples(text);
  const std::map<std::string, double> expected = {
      {"edgephys_requests_rejected_total{reason=\"bad_token\"}", 2},
      {"edgephys_requests_rejected_total{reason=\"expired_token\"}", 1},
      {"edgephys_requests_rejected_total{reason=\"replayed_token\"}", 0},
      {"edgephys_requests_rejected_total{reason=\"room_full\"}", 0},
      {"edgephys_requests_rejected_total{reason=\"invalid_message\"}", 0},
      {"edgephys_requests_rejected_total{reason=\"bad_cookie\"}", 1},
      {"edgephys_disconnects_total{reason=\"timeout\"}", 1},
      {"edgephys_disconnects_total{reason=\"client_left\"}", 2},
      {"edgephys_disconnects_total{reason=\"server_shutdown\"}", 0},
      {"edgephys_disconnects_total{reason=\"reliable_overflow\"}", 0},
  };
  ASSERT_NO_FATAL_FAILURE(ExpectSamples(samples, expected, text));
  int reject_series = 0;
  int disconnect_series = 0;
  for (const auto& [series, value] : samples) {
    if (series.starts_with("edgephys_requests_rejected_total{")) ++reject_series;
    if (series.starts_with("edgephys_disconnects_total{")) ++disconnect_series;
  }
  EXPECT_EQ(reject_series, static_cast<int>(kRejectReasonCount) - 1);
  EXPECT_EQ(disconnect_series, static_cast<int>(kDisconnectReasonCount) - 1);
  EXPECT_THAT(text, Not(HasSubstr("reason=\"none\"")));
}

TEST_F(MetricsExporterTest, HistogramBucketsAreCumulative) {
  // rtt bounds: 0.0005 0.001 0.0025 0.005 0.01 0.025 0.05 0.1 0.25 0.5
  counters_.rtt_seconds.Observe(0.0002);  // le 0.0005
  counters_.rtt_seconds.Observe(0.004);   // le 0.005
  counters_.rtt_seconds.Observe(0.004);   // le 0.005
  counters_.rtt_seconds.Observe(0.02);    // le 0.025
  counters_.rtt_seconds.Observe(2.0);     // +Inf only
  counters_.tick_seconds.Observe(0.00003);

  const std::string text = Scrape(*exporter_);
  const auto samples = ParseSamples(text);
  const std::vector<std::pair<std::string, double>> rtt_buckets = {
      {"0.0005", 1}, {"0.001", 1}, {"0.0025", 1}, {"0.005", 3}, {"0.01", 3}, {"0.025", 4},
      {"0.05", 4},   {"0.1", 4},   {"0.25", 4},   {"0.5", 4},   {"+Inf", 5},
  };
  double previous = 0;
  for (const auto& [le, want] : rtt_buckets) {
    const std::string series = "edgephys_rtt_seconds_bucket{le=\"" + le + "\"}";
    auto it = samples.find(series);
    ASSERT_NE(it, samples.end()) << series << " missing from:\n" << text;
    EXPECT_EQ(it->second, want) << series;
    EXPECT_GE(it->second, previous) << series << " not cumulative";
    previous = it->second;
  }
  ASSERT_TRUE(samples.contains("edgephys_rtt_seconds_count"));
  EXPECT_EQ(samples.at("edgephys_rtt_seconds_count"), 5);
  EXPECT_EQ(samples.at("edgephys_rtt_seconds_count"),
            samples.at("edgephys_rtt_seconds_bucket{le=\"+Inf\"}"));
  ASSERT_TRUE(samples.contains("edgephys_rtt_seconds_sum"));
  EXPECT_NEAR(samples.at("edgephys_rtt_seconds_sum"), 0.0002 + 0.004 + 0.004 + 0.02 + 2.0, 1e-6);

  EXPECT_EQ(samples.at("edgephys_tick_duration_seconds_bucket{le=\"1e-05\"}"), 0);
  EXPECT_EQ(samples.at("edgephys_tick_duration_seconds_bucket{le=\"5e-05\"}"), 1);
  EXPECT_EQ(samples.at("edgephys_tick_duration_seconds_bucket{le=\"+Inf\"}"), 1);
  EXPECT_EQ(samples.at("edgephys_tick_duration_seconds_count"), 1);
  // Exactly one +Inf bucket per histogram (rtt, tick duration, physics step).
  size_t inf_lines = 0;
  for (size_t pos = text.find("le=\"+Inf\""); pos != std::string::npos;
       pos = text.find("le=\"+Inf\"", pos + 1)) {
    ++inf_lines;
  }
  EXPECT_EQ(inf_lines, 3u);
}

TEST_F(MetricsExporterTest, ValuesAreReadAtScrapeTime) {
  RelayCounters::Inc(counters_.packets_received, 1);
  EXPECT_EQ(ParseSamples(Scrape(*exporter_)).at("edgephys_packets_received_total"), 1);
  RelayCounters::Inc(counters_.packets_received, 99);
  counters_.clients = 4;
  counters_.clients.fetch_sub(1);
  const auto samples = ParseSamples(Scrape(*exporter_));
  EXPECT_EQ(samples.at("edgephys_packets_received_total"), 100);
  EXPECT_EQ(samples.at("edgephys_clients"), 3);
}

TEST_F(MetricsExporterTest, RoomWorkSecondsPerRoomAndClosedRoomsGo) {
  counters_.room_work.Add("arena", 1.5);
  counters_.room_work.Add("lobby", 0.25);
  std::string text = Scrape(*exporter_);
  EXPECT_THAT(text, HasSubstr("# TYPE edgephys_room_update_seconds_total counter\n"));
  auto samples = ParseSamples(text);
  EXPECT_EQ(samples.at("edgephys_room_update_seconds_total{room=\"arena\"}"), 1.5);
  EXPECT_EQ(samples.at("edgephys_room_update_seconds_total{room=\"lobby\"}"), 0.25);
  EXPECT_EQ(samples.count("edgephys_room_update_seconds_total{room=\"~other\"}"), 0u);
  counters_.room_work.Remove("lobby");
  samples = ParseSamples(Scrape(*exporter_));
  EXPECT_EQ(samples.count("edgephys_room_update_seconds_total{room=\"lobby\"}"), 0u);
  EXPECT_EQ(samples.at("edgephys_room_update_seconds_total{room=\"arena\"}"), 1.5);
}

// process_* read from /proc/self: values that follow what this process does between scrapes.
TEST_F(MetricsExporterTest, ProcessFamiliesFollowTheProcess) {
  auto before = ParseSamples(Scrape(*exporter_));
  for (const char* name : {"process_cpu_seconds_total", "process_resident_memory_bytes",
                           "process_virtual_memory_bytes", "process_open_fds", "process_max_fds",
                           "process_start_time_seconds", "process_threads"}) {
    ASSERT_TRUE(before.count(name)) << name << " missing";
  }
  // Ten more descriptors and 64 MiB touched: both must show in the next scrape.
  std::vector<FILE*> files;
  for (int i = 0; i < 10; ++i) files.push_back(std::fopen("/dev/null", "r"));
  std::vector<char> block(64u << 20, 1);
  volatile uint64_t spin = 0;
  for (uint64_t i = 0; i < 200000000u; ++i) spin = spin + i;  // CPU time
  auto after = ParseSamples(Scrape(*exporter_));
  EXPECT_GE(after["process_open_fds"], before["process_open_fds"] + 10);
  EXPECT_GE(after["process_resident_memory_bytes"],
            before["process_resident_memory_bytes"] + 60.0 * (1 << 20));
  EXPECT_GT(after["process_cpu_seconds_total"], before["process_cpu_seconds_total"]);
  const double now = static_cast<double>(time(nullptr));
  EXPECT_LE(after["process_start_time_seconds"], now + 1);
  EXPECT_GT(after["process_start_time_seconds"], now - 3600);
  EXPECT_GE(after["process_threads"], 2);  // this thread and the HTTP server's
  for (FILE* f : files) std::fclose(f);
  EXPECT_EQ(block[12345], 1);
}

TEST_F(MetricsExporterTest, PassesPromtoolCheckMetrics) {
  const char* kPromtool = "/usr/bin/promtool";
  if (access(kPromtool, X_OK) != 0) {
    GTEST_SKIP() << kPromtool << " not installed (Debian package `prometheus`); lint skipped";
  }
  // Non-zero values so every family has interesting samples.
  RelayCounters::Inc(counters_.packets_received, 42);
  counters_.RejectPacket(DropReason::kMalformed);
  counters_.RejectRequest(3);
  counters_.CountDisconnect(DisconnectReason::kKicked);
  counters_.rtt_seconds.Observe(0.01);
  counters_.tick_seconds.Observe(0.001);
  // Room names are the clients' bytes: quotes, backslashes, newlines, invalid UTF-8.
  counters_.room_work.Add("a \"quoted\" \\ room\n\xff\xfe", 0.5);
  counters_.room_work.Add("plain", 0.25);
  for (size_t i = 0; i <= counters_.room_work.max_rooms(); ++i) {  // past the cap: "~other"
    counters_.room_work.Add("room-" + std::to_string(i), 0.001);
  }
  const std::string text = Scrape(*exporter_);
  ASSERT_FALSE(text.empty());
  EXPECT_THAT(text, HasSubstr("edgephys_room_update_seconds_total{room=\"plain\"} 0.25"));
  EXPECT_THAT(text, HasSubstr("edgephys_room_update_seconds_total{room=\"~other\"} "));

  char path[] = "/tmp/edgephys_metrics_XXXXXX";
  const int fd = mkstemp(path);
  ASSERT_GE(fd, 0);
  close(fd);
  {
    std::ofstream out(path, std::ios::binary);
    out << text;
  }
  const std::string command = std::string(kPromtool) + " check metrics < " + path + " 2>&1";
  FILE* pipe = popen(command.c_str(), "r");
  ASSERT_NE(pipe, nullptr);
  std::string output;
  char buffer[512];
  size_t n;
  while ((n = fread(buffer, 1, sizeof(buffer), pipe)) > 0) output.append(buffer, n);
  const int status = pclose(pipe);
  std::remove(path);

  ASSERT_TRUE(WIFEXITED(status)) << output;
  EXPECT_EQ(WEXITSTATUS(status), 0) << "promtool output:\n" << output << "\nexposition:\n" << text;
  EXPECT_EQ(output, "") << "promtool reported problems:\n" << output;
}

TEST(MetricsExporterStartTest, RejectsBadArguments) {
  RelayCounters counters;
  auto no_counters = MetricsExporter::Start("127.0.0.1:0", nullptr);
  ASSERT_FALSE(no_counters.ok());
  EXPECT_EQ(no_counters.status().code(), StatusCode::kInvalidArgument);

  auto empty = MetricsExporter::Start("", RelayMetrics(&counters));
  ASSERT_FALSE(empty.ok());
  EXPECT_EQ(empty.status().code(), StatusCode::kInvalidArgument);

  auto several = MetricsExporter::Start("127.0.0.1:0,127.0.0.1:0", RelayMetrics(&counters));
  ASSERT_FALSE(several.ok());
  EXPECT_EQ(several.status().code(), StatusCode::kInvalidArgument);

  auto garbage = MetricsExporter::Start("not-an-address:xyz", RelayMetrics(&counters));
  ASSERT_FALSE(garbage.ok());
  EXPECT_EQ(garbage.status().code(), StatusCode::kIoError);
}

TEST(MetricsExporterStartTest, PortInUseIsAnIoError) {
  RelayCounters counters;
  auto first = MetricsExporter::Start("127.0.0.1:0", RelayMetrics(&counters));
  ASSERT_TRUE(first.ok()) << first.status().message();
  const std::string taken = "127.0.0.1:" + std::to_string((*first)->port());
  auto second = MetricsExporter::Start(taken, RelayMetrics(&counters));
  ASSERT_FALSE(second.ok());
  EXPECT_EQ(second.status().code(), StatusCode::kIoError);
}

TEST(MetricsExporterStartTest, DestructorStopsServer) {
  curl_global_init(CURL_GLOBAL_DEFAULT);
  RelayCounters counters;
  auto started = MetricsExporter::Start("127.0.0.1:0", RelayMetrics(&counters));
  ASSERT_TRUE(started.ok()) << started.status().message();
  std::unique_ptr<MetricsExporter> exporter = std::move(started.value());
  const std::string url = MetricsUrl(*exporter);
  HttpResponse before = HttpGet(url);
  ASSERT_TRUE(before.ok) << before.error;
  EXPECT_EQ(before.status, 200);

  exporter.reset();
  HttpResponse after = HttpGet(url);
  EXPECT_FALSE(after.ok) << "server still answering after destruction, status " << after.status;
  curl_global_cleanup();
}

}  // namespace
}  // namespace edgephys
