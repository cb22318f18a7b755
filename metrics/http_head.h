// ParseRequestHead: the HTTP/1.1 request-head checks the gate (metrics/http_gate.h) makes on
// the bytes a connection sent so far, before a worker sees them. Pure: no I/O, no state, so
// the gate thread calls it on every read and the fuzz target (tests/fuzz/http_head_fuzz.cc)
// calls it on anything.
//
// Refused (status, code, message): a head over `max_head_bytes` (431 header_too_large), over
// `max_headers` header lines (431 too_many_headers), a control byte (400), a request line
// without method and target (400), a header line without a name (400), whitespace after the
// Authorization value (400 bad_authorization), Transfer-Encoding (411: bodies need
// Content-Length), a Content-Length that is not a decimal of at most 18 digits or two that
// disagree (400), a body over `max_body_bytes` (413 body_too_large).
//
// Cost: O(bytes of the head); allocates only the method and path.
#pragma once

#include <cstddef>
#include <string>
#include <string_view>

namespace edgephys::http {

struct HeadLimits {
  size_t max_head_bytes = 16 * 1024;
  size_t max_headers = 100;
  size_t max_body_bytes = 64 * 1024;
};

struct RequestHead {
  enum class Outcome { kNeedMore, kComplete, kRefused };
  Outcome outcome = Outcome::kNeedMore;
  // kRefused: the answer to send.
  int status = 0;
  const char* code = "";
  std::string message;
  // kComplete:
  std::string method, path;
  size_t head_bytes = 0;     // through the blank line
  size_t request_bytes = 0;  // head + Content-Length (0 without one)
  bool expect_continue = false;
};

// `in`: the bytes received so far (the head may be incomplete).
RequestHead ParseRequestHead(std::string_view in, const HeadLimits& limits);

}  // namespace edgephys::http
