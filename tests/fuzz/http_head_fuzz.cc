// http_head_fuzz: the request-head checks of the HTTP gate in front of the admin API and
// /metrics (metrics/http_head.h), on any bytes, with small and default limits. Asserts the
// parser's contract: a complete head lies within the input and the limits; a refusal names
// a status >= 400 and a cause.
#include <cstddef>
#include <cstdint>
#include <cstdlib>
#include <string_view>

#include "metrics/http_head.h"

namespace {

void Check(std::string_view in, const edgephys::http::HeadLimits& limits) {
  using Outcome = edgephys::http::RequestHead::Outcome;
  const edgephys::http::RequestHead h = edgephys::http::ParseRequestHead(in, limits);
  bool ok = true;
  switch (h.outcome) {
    case Outcome::kNeedMore:
      ok = in.find("\r\n\r\n") == std::string_view::npos && in.size() <= limits.max_head_bytes;
      break;
    case Outcome::kComplete:
      ok = h.head_bytes <= in.size() && h.head_bytes <= limits.max_head_bytes &&
           h.request_bytes >= h.head_bytes && h.request_bytes - h.head_bytes <= limits.max_body_bytes;
      break;
    case Outcome::kRefused:
      ok = h.status >= 400 && !h.message.empty();
      break;
  }
  if (!ok) std::abort();
}

}  // namespace

extern "C" int LLVMFuzzerTestOneInput(const uint8_t* data, size_t size) {
  const std::string_view in(reinterpret_cast<const char*>(data), size);
  Check(in, edgephys::http::HeadLimits{});
  Check(in, edgephys::http::HeadLimits{64, 4, 16});
  return 0;
}
