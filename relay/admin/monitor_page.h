// The monitor page (relay/admin/monitor.html), embedded in the binary at build time
// (relay/admin/CMakeLists.txt generates its definition). Served at GET /monitor.
#pragma once

namespace edgephys::admin {

extern const char kMonitorPage[];

}  // namespace edgephys::admin
