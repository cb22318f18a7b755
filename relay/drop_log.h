// DropLog: rate-limited warnings for dropped untrusted input. At most one line per reason per
// second (per thread), with the number suppressed since the last line, so a flood cannot fill
// the log. Thread-safety: one instance per thread (DropLogOfThisThread()).
#pragma once

#include <spdlog/spdlog.h>

#include <cstdint>
#include <map>
#include <string>
#include <string_view>

#include "protocol/datagram_socket.h"

namespace edgephys {

class DropLog {
 public:
  // Notes one drop of `what` for `reason` from `from` at relay time `now` (seconds).
  void Note(std::string_view what, std::string_view reason, const Endpoint& from, double now) {
    Entry& e = entries_[std::string(reason)];
    ++e.suppressed;
    if (now - e.last >= 1.0) {
      spdlog::warn("{} from {}:{}: {} ({} since last report)", what, from.address().to_string(),
                   from.port(), reason, e.suppressed);
      e.last = now;
      e.suppressed = 0;
    }
  }

 private:
  struct Entry {
    double last = -1e9;
    uint64_t suppressed = 0;
  };
  std::map<std::string, Entry, std::less<>> entries_;
};

inline DropLog& DropLogOfThisThread() {
  static thread_local DropLog log;
  return log;
}

}  // namespace edgephys
