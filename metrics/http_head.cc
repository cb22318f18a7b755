#include "metrics/http_head.h"

#include <algorithm>
#include <cctype>

namespace edgephys::http {
namespace {

std::string Lower(std::string_view s) {
  std::string out(s);
  for (char& c : out) c = static_cast<char>(std::tolower(static_cast<unsigned char>(c)));
  return out;
}

RequestHead Refuse(int status, const char* code, std::string message) {
  RequestHead h;
  h.outcome = RequestHead::Outcome::kRefused;
  h.status = status;
  h.code = code;
  h.message = std::move(message);
  return h;
}

}  // namespace

RequestHead ParseRequestHead(std::string_view in, const HeadLimits& limits) {
  const size_t end = in.find("\r\n\r\n");
  if (end == std::string_view::npos) {
    if (in.size() > limits.max_head_bytes) {
      return Refuse(431, "header_too_large", "the request head exceeds the limit");
    }
    return RequestHead{};
  }
  const size_t head_len = end + 4;
  if (head_len > limits.max_head_bytes) {
    return Refuse(431, "header_too_large", "the request head exceeds the limit");
  }
  const std::string_view head = in.substr(0, end);
  RequestHead out;
  size_t headers = 0;
  long long content_length = -1;
  size_t pos = 0;
  for (bool first = true; pos <= head.size(); first = false) {
    size_t eol = head.find("\r\n", pos);
    if (eol == std::string_view::npos) eol = head.size();
    const std::string_view line = head.substr(pos, eol - pos);
    pos = eol + 2;
    for (char ch : line) {
      const auto u = static_cast<unsigned char>(ch);
      if ((u < 0x20 && u != '\t') || u == 0x7f) {
        return Refuse(400, "bad_request", "a control byte in the request head");
      }
    }
    if (first) {
      const size_t sp1 = line.find(' ');
      const size_t sp2 = sp1 == std::string_view::npos ? sp1 : line.find(' ', sp1 + 1);
      if (sp2 == std::string_view::npos) return Refuse(400, "bad_request", "malformed request line");
      out.method = std::string(line.substr(0, sp1));
      out.path = std::string(line.substr(sp1 + 1, sp2 - sp1 - 1));
      continue;
    }
    if (++headers > limits.max_headers) {
      return Refuse(431, "too_many_headers",
                    "more than " + std::to_string(limits.max_headers) + " header lines");
    }
    const size_t colon = line.find(':');
    if (colon == std::string_view::npos || colon == 0) {
      return Refuse(400, "bad_request", "a header line without a name");
    }
    const std::string name = Lower(line.substr(0, colon));
    const std::string_view raw = line.substr(colon + 1);
    const size_t b = raw.find_first_not_of(" \t");
    std::string_view value = b == std::string_view::npos ? std::string_view{} : raw.substr(b);
    if (name == "authorization" && !value.empty() && (value.back() == ' ' || value.back() == '\t')) {
      return Refuse(400, "bad_authorization", "whitespace after the Authorization value");
    }
    while (!value.empty() && (value.back() == ' ' || value.back() == '\t')) value.remove_suffix(1);
    if (name == "transfer-encoding") {
      return Refuse(411, "length_required", "send the body with Content-Length");
    }
    if (name == "content-length") {
      if (value.empty() || value.size() > 18 ||
          value.find_first_not_of("0123456789") != std::string_view::npos) {
        return Refuse(400, "bad_request", "Content-Length is not a number");
      }
      const long long v = std::stoll(std::string(value));
      if (content_length >= 0 && v != content_length) {
        return Refuse(400, "bad_request", "conflicting Content-Length headers");
      }
      content_length = v;
    }
    if (name == "expect" && Lower(value) == "100-continue") out.expect_continue = true;
  }
  if (content_length > static_cast<long long>(limits.max_body_bytes)) {
    return Refuse(413, "body_too_large", "the request body exceeds the limit");
  }
  out.outcome = RequestHead::Outcome::kComplete;
  out.head_bytes = head_len;
  out.request_bytes = head_len + static_cast<size_t>(std::max(0LL, content_length));
  return out;
}

}  // namespace edgephys::http
