#include "metrics/http_head.h"

#include <gtest/gtest.h>

#include <random>
#include <string>

namespace edgephys::http {
namespace {

using Outcome = RequestHead::Outcome;

RequestHead Parse(const std::string& in, HeadLimits limits = {}) { return ParseRequestHead(in, limits); }

TEST(RequestHeadTest, ACompleteHeadGivesMethodPathAndTheRequestLength) {
  const std::string in = "POST /v1/rooms HTTP/1.1\r\nHost: x\r\nContent-Length: 12\r\n\r\n{\"id\":\"a\"}";
  RequestHead h = Parse(in);
  ASSERT_EQ(h.outcome, Outcome::kComplete);
  EXPECT_EQ(h.method, "POST");
  EXPECT_EQ(h.path, "/v1/rooms");
  EXPECT_EQ(h.head_bytes, in.find("\r\n\r\n") + 4);
  EXPECT_EQ(h.request_bytes, h.head_bytes + 12);
  EXPECT_FALSE(h.expect_continue);
}

TEST(RequestHeadTest, EveryPrefixOfAHeadNeedsMore) {
  const std::string in = "GET /healthz HTTP/1.1\r\nExpect: 100-Continue\r\n\r\n";
  for (size_t n = 0; n + 1 < in.size(); ++n) {
    EXPECT_EQ(Parse(in.substr(0, n)).outcome, Outcome::kNeedMore) << n;
  }
  RequestHead h = Parse(in);
  ASSERT_EQ(h.outcome, Outcome::kComplete);
  EXPECT_TRUE(h.expect_continue);
  EXPECT_EQ(h.request_bytes, in.size());
}

TEST(RequestHeadTest, BadHeadsAreRefusedWithTheirCause) {
  struct Case {
    std::string in;
    int status;
    std::string code;
  };
  const std::string big(20000, 'a');
  const Case cases[] = {
      {"GET /\r\n\r\n", 400, "bad_request"},
      {"GET / HTTP/1.1\r\nX\x01: y\r\n\r\n", 400, "bad_request"},
      {"GET / HTTP/1.1\r\n: y\r\n\r\n", 400, "bad_request"},
      {"GET / HTTP/1.1\r\nnocolon\r\n\r\n", 400, "bad_request"},
      {"GET / HTTP/1.1\r\nAuthorization: Bearer k \r\n\r\n", 400, "bad_authorization"},
      {"POST / HTTP/1.1\r\nTransfer-Encoding: chunked\r\n\r\n", 411, "length_required"},
      {"POST / HTTP/1.1\r\nContent-Length: -1\r\n\r\n", 400, "bad_request"},
      {"POST / HTTP/1.1\r\nContent-Length: 1234567890123456789\r\n\r\n", 400, "bad_request"},
      {"POST / HTTP/1.1\r\nContent-Length: 3\r\nContent-Length: 4\r\n\r\n", 400, "bad_request"},
      {"POST / HTTP/1.1\r\nContent-Length: 70000\r\n\r\n", 413, "body_too_large"},
      {"GET / HTTP/1.1\r\nX: " + big + "\r\n\r\n", 431, "header_too_large"},
      {"GET / HTTP/1.1\r\nX: " + big, 431, "header_too_large"},  // incomplete and too long
  };
  for (const Case& c : cases) {
    RequestHead h = Parse(c.in);
    EXPECT_EQ(h.outcome, Outcome::kRefused) << c.in.substr(0, 60);
    EXPECT_EQ(h.status, c.status) << c.in.substr(0, 60);
    EXPECT_EQ(h.code, c.code) << c.in.substr(0, 60);
    EXPECT_FALSE(h.message.empty());
  }
  std::string many = "GET / HTTP/1.1\r\n";
  for (int i = 0; i < 101; ++i) many += "X: y\r\n";
  RequestHead h = Parse(many + "\r\n");
  EXPECT_EQ(h.status, 431);
  EXPECT_EQ(std::string(h.code), "too_many_headers");
}

// Random heads built from HTTP-ish pieces: whatever the outcome, a complete head lies within
// the input and the limits, and a refusal carries a status and a message.
TEST(RequestHeadTest, RandomHeadsKeepTheInvariants) {
  std::mt19937 rng(7);
  const char* pieces[] = {"GET ", "POST ", "/", "x", " ", "HTTP/1.1", "\r\n", "\r\n\r\n", ":",
                          "Content-Length", "Expect", "100-continue", "Authorization", "\t",
                          "12", "99999999", "\x01", "Transfer-Encoding", "0"};
  const HeadLimits limits{256, 8, 64};
  for (int i = 0; i < 20000; ++i) {
    std::string in;
    const int n = static_cast<int>(rng() % 40);
    for (int k = 0; k < n; ++k) in += pieces[rng() % std::size(pieces)];
    RequestHead h = ParseRequestHead(in, limits);
    switch (h.outcome) {
      case Outcome::kNeedMore:
        EXPECT_EQ(in.find("\r\n\r\n"), std::string::npos);
        EXPECT_LE(in.size(), limits.max_head_bytes);
        break;
      case Outcome::kComplete:
        EXPECT_LE(h.head_bytes, in.size());
        EXPECT_LE(h.head_bytes, limits.max_head_bytes);
        EXPECT_GE(h.request_bytes, h.head_bytes);
        EXPECT_LE(h.request_bytes - h.head_bytes, limits.max_body_bytes);
        break;
      case Outcome::kRefused:
        EXPECT_GE(h.status, 400);
        EXPECT_FALSE(h.message.empty());
        break;
    }
  }
}

}  // namespace
}  // namespace edgephys::http
