#include "metrics/metrics_exporter.h"

#include <prometheus/client_metric.h>
#include <prometheus/collectable.h>
#include <httplib.h>
#include <prometheus/metric_family.h>
#include <prometheus/metric_type.h>
#include <prometheus/text_serializer.h>

#include <algorithm>
#include <cstddef>
#include <exception>
#include <limits>
#include <string>
#include <utility>
#include <vector>

#include "metrics/http_gate.h"
#include "metrics/process_metrics.h"

#ifndef EDGEPHYS_VERSION
#define EDGEPHYS_VERSION "0.1.0"
#endif

namespace edgephys {
namespace {

prometheus::MetricFamily ToPrometheus(MetricFamilyData&& data) {
  prometheus::MetricFamily family;
  family.name = std::move(data.name);
  family.help = std::move(data.help);
  switch (data.kind) {
    case MetricKind::kGauge: family.type = prometheus::MetricType::Gauge; break;
    case MetricKind::kCounter: family.type = prometheus::MetricType::Counter; break;
    case MetricKind::kHistogram: family.type = prometheus::MetricType::Histogram; break;
  }
  for (MetricSample& s : data.samples) {
    prometheus::ClientMetric metric;
    for (auto& [name, value] : s.labels) metric.label.push_back({std::move(name), std::move(value)});
    if (data.kind == MetricKind::kCounter) {
      metric.counter.value = s.value;
    } else {
      metric.gauge.value = s.value;
    }
    family.metric.push_back(std::move(metric));
  }
  for (const MetricHistogram& h : data.histograms) {
    prometheus::ClientMetric metric;
    const size_t n = std::min(h.bounds.size() + 1, h.cumulative.size());
    for (size_t i = 0; i < n; ++i) {
      prometheus::ClientMetric::Bucket bucket;
      bucket.cumulative_count = h.cumulative[i];
      bucket.upper_bound =
          i < h.bounds.size() ? h.bounds[i] : std::numeric_limits<double>::infinity();
      metric.histogram.bucket.push_back(bucket);
    }
    // _count equals the +Inf bucket by construction.
    metric.histogram.sample_count = n > 0 ? h.cumulative[n - 1] : 0;
    metric.histogram.sample_sum = h.sum;
    family.metric.push_back(std::move(metric));
  }
  return family;
}

class SourceCollectable : public prometheus::Collectable {
 public:
  explicit SourceCollectable(std::shared_ptr<const MetricSource> source)
      : source_(std::move(source)) {}

  std::vector<prometheus::MetricFamily> Collect() const override {
    std::vector<prometheus::MetricFamily> families;
    prometheus::MetricFamily info;
    info.name = "edgephys_build_info";
    info.help = "edgephys build information; the value is always 1.";
    info.type = prometheus::MetricType::Gauge;
    prometheus::ClientMetric metric;
    metric.label.push_back({"version", EDGEPHYS_VERSION});
    metric.gauge.value = 1;
    info.metric.push_back(std::move(metric));
    families.push_back(std::move(info));

    std::vector<MetricFamilyData> data;
    source_->Collect(&data);
    families.reserve(families.size() + data.size() + 8);
    for (MetricFamilyData& d : data) families.push_back(ToPrometheus(std::move(d)));
    AppendProcessFamilies(&families);
    return families;
  }

 private:
  std::shared_ptr<const MetricSource> source_;
};

}  // namespace

Result<std::unique_ptr<MetricsExporter>> MetricsExporter::Start(const std::string& bind_address,
                                                                std::shared_ptr<const MetricSource> source) {
  if (source == nullptr) {
    return Status(StatusCode::kInvalidArgument, "metrics exporter: source is null");
  }
  if (bind_address.empty() || bind_address.find(',') != std::string::npos) {
    return Status(StatusCode::kInvalidArgument,
                  "metrics exporter: bind address must be one host:port");
  }

  auto collectable = std::make_shared<SourceCollectable>(std::move(source));
  http::GateOptions options;
  // A bare "port" listens on every IPv4 address.
  options.address = bind_address.find(':') == std::string::npos ? "0.0.0.0:" + bind_address
                                                                 : bind_address;
  options.workers = 2;
  options.max_body_bytes = 0;
  auto gate = std::make_unique<http::HttpGate>(std::move(options));
  std::weak_ptr<prometheus::Collectable> weak = collectable;
  gate->routes().Get("/metrics", [weak](const httplib::Request&, httplib::Response& res) {
    auto live = weak.lock();
    if (!live) {
      res.status = 503;
      return;
    }
    res.set_content(prometheus::TextSerializer().Serialize(live->Collect()),
                    "text/plain; version=0.0.4; charset=utf-8");
  });
  if (Status st = gate->Start(); !st.ok()) {
    return Status(StatusCode::kIoError, "metrics exporter: cannot listen on bind address",
                  std::string(st.reason()));
  }
  const uint16_t port = gate->port();
  return std::unique_ptr<MetricsExporter>(
      new MetricsExporter(std::move(collectable), std::move(gate), port));
}

MetricsExporter::MetricsExporter(std::shared_ptr<prometheus::Collectable> collectable,
                                 std::unique_ptr<http::HttpGate> gate, uint16_t port)
    : collectable_(std::move(collectable)), gate_(std::move(gate)), port_(port) {}

MetricsExporter::~MetricsExporter() {
  // Stop the server (its workers joined) before the collectable goes away, so no scrape can
  // read the source after we return.
  gate_.reset();
  collectable_.reset();
}

}  // namespace edgephys
