// The standard Prometheus process_* families for the calling process, read from /proc/self
// at scrape time (the names and units the Prometheus client libraries' process collectors
// use, so dashboards and alerts written for them work unchanged):
//   process_cpu_seconds_total       counter  user + system CPU time, seconds
//   process_resident_memory_bytes   gauge    resident set size, bytes
//   process_virtual_memory_bytes    gauge    virtual memory size, bytes
//   process_open_fds                gauge    open file descriptors
//   process_max_fds                 gauge    RLIMIT_NOFILE soft limit
//   process_start_time_seconds      gauge    start time, seconds since the Unix epoch
//   process_threads                 gauge    threads in the process
// Linux only. A family whose source cannot be read (no /proc) is left out, never reported as 0.
// Thread-safe; allocates; meant for a scrape thread, not the relay's loop.
#pragma once

#include <prometheus/metric_family.h>

#include <vector>

namespace edgephys {

// Appends the families above that could be read to `out`.
void AppendProcessFamilies(std::vector<prometheus::MetricFamily>* out);

}  // namespace edgephys
