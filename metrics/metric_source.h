// MetricSource: what the Prometheus exporter (metrics_exporter.h) reads at scrape time. The
// layer that owns the numbers (the relay: relay/relay_metrics.h) implements it; metrics/ knows
// nothing of that layer's types. Plain values, no Prometheus types, so an implementation needs
// only this header.
#pragma once

#include <cstdint>
#include <string>
#include <utility>
#include <vector>

namespace edgephys {

enum class MetricKind { kGauge, kCounter, kHistogram };

// One series: its labels (name, value) and its value. A counter's family name carries its
// single `_total` suffix itself.
struct MetricSample {
  std::vector<std::pair<std::string, std::string>> labels;
  double value = 0;
};

// One histogram series: upper bounds ascending (+Inf implied), the cumulative count at each
// bound plus one more for +Inf (so cumulative.size() == bounds.size() + 1, non-decreasing), and
// the sum of the observations.
struct MetricHistogram {
  std::vector<double> bounds;
  std::vector<uint64_t> cumulative;
  double sum = 0;
};

struct MetricFamilyData {
  std::string name;  // Prometheus metric name, e.g. "edgephys_rooms"
  std::string help;
  MetricKind kind = MetricKind::kGauge;
  std::vector<MetricSample> samples;        // kGauge, kCounter
  std::vector<MetricHistogram> histograms;  // kHistogram (one unlabelled series)
};

class MetricSource {
 public:
  virtual ~MetricSource() = default;
  // Appends the current families to `out`. Called on the exporter's HTTP threads, possibly
  // concurrently with itself and with the source's writers: an implementation reads only
  // atomics or takes its own locks, and must not throw.
  virtual void Collect(std::vector<MetricFamilyData>* out) const = 0;
};

}  // namespace edgephys
