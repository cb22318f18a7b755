#include "metrics/process_metrics.h"

#include <dirent.h>
#include <sys/resource.h>
#include <unistd.h>

#include <cstdlib>
#include <fstream>
#include <sstream>
#include <string>
#include <vector>

namespace edgephys {
namespace {

prometheus::MetricFamily One(const char* name, const char* help, prometheus::MetricType type,
                             double value) {
  prometheus::ClientMetric m;
  if (type == prometheus::MetricType::Counter) {
    m.counter.value = value;
  } else {
    m.gauge.value = value;
  }
  return prometheus::MetricFamily{name, help, type, {m}};
}

// Fields of /proc/self/stat after the command name (which may hold spaces and parentheses):
// fields[0] is field 3 (state) of proc(5).
std::vector<std::string> StatFields() {
  std::ifstream in("/proc/self/stat");
  std::string line;
  if (!std::getline(in, line)) return {};
  const size_t close = line.rfind(')');
  if (close == std::string::npos) return {};
  std::istringstream rest(line.substr(close + 1));
  std::vector<std::string> fields;
  for (std::string f; rest >> f;) fields.push_back(f);
  return fields;
}

double Num(const std::string& text) { return std::strtod(text.c_str(), nullptr); }

double BootTimeSeconds() {
  std::ifstream in("/proc/stat");
  for (std::string key; in >> key;) {
    if (key == "btime") {
      double t = -1;
      in >> t;
      return t;
    }
    in.ignore(1 << 20, '\n');
  }
  return -1;
}

}  // namespace

void AppendProcessFamilies(std::vector<prometheus::MetricFamily>* out) {
  using prometheus::MetricType;
  const std::vector<std::string> f = StatFields();
  const double ticks = static_cast<double>(sysconf(_SC_CLK_TCK));
  const double page = static_cast<double>(sysconf(_SC_PAGESIZE));
  // proc(5) field n is f[n - 3].
  if (f.size() >= 22 && ticks > 0 && page > 0) {
    const double utime = Num(f[14 - 3]), stime = Num(f[15 - 3]);
    out->push_back(One("process_cpu_seconds_total", "Total user and system CPU time spent in seconds.",
                       MetricType::Counter, (utime + stime) / ticks));
    out->push_back(One("process_threads", "Number of OS threads in the process.", MetricType::Gauge,
                       Num(f[20 - 3])));
    out->push_back(One("process_virtual_memory_bytes", "Virtual memory size in bytes.",
                       MetricType::Gauge, Num(f[23 - 3])));
    out->push_back(One("process_resident_memory_bytes", "Resident memory size in bytes.",
                       MetricType::Gauge, Num(f[24 - 3]) * page));
    const double boot = BootTimeSeconds();
    if (boot >= 0) {
      out->push_back(One("process_start_time_seconds",
                         "Start time of the process since unix epoch in seconds.", MetricType::Gauge,
                         boot + Num(f[22 - 3]) / ticks));
    }
  }
  if (DIR* d = opendir("/proc/self/fd")) {
    double n = 0;
    while (const dirent* e = readdir(d)) {
      if (e->d_name[0] != '.') ++n;
    }
    closedir(d);
    out->push_back(One("process_open_fds", "Number of open file descriptors.", MetricType::Gauge,
                       n - 1));  // less the descriptor opendir itself holds
  }
  rlimit lim{};
  if (getrlimit(RLIMIT_NOFILE, &lim) == 0 && lim.rlim_cur != RLIM_INFINITY) {
    out->push_back(One("process_max_fds", "Maximum number of open file descriptors.",
                       MetricType::Gauge, static_cast<double>(lim.rlim_cur)));
  }
}

}  // namespace edgephys
