#include "relay/admin/admin_http.h"

#include <httplib.h>
#include <openssl/crypto.h>
#include <openssl/sha.h>
#include <spdlog/spdlog.h>

#include <chrono>
#include <exception>
#include <regex>
#include <utility>
#include <vector>

#include "metrics/http_gate.h"
#include "protocol/endpoint.h"
#include "relay/admin/admin_routes.h"

namespace edgephys::admin {
namespace {

using nlohmann::json;

void WriteJson(httplib::Response& res, const AdminReply& reply) {
  res.status = reply.status;
  res.set_header("Cache-Control", "no-store");
  // Room names come from join tokens and may hold any bytes: invalid UTF-8 is replaced, never
  // thrown on.
  res.set_content(reply.body.dump(-1, ' ', false, nlohmann::json::error_handler_t::replace),
                  "application/json");
}

// The JSON error for statuses httplib produces itself (no route, body too large, bad HTTP).
AdminReply ErrorFor(int status) {
  switch (status) {
    case 404: return AdminError(404, "not_found", "no such endpoint (see docs/admin-api.md)");
    case 413: return AdminError(413, "body_too_large", "the request body exceeds the limit");
    case 400: return AdminError(400, "bad_request", "malformed HTTP request");
    default: return AdminError(status, "http_error", "HTTP error " + std::to_string(status));
  }
}

std::string BearerOf(const httplib::Request& req) {
  std::string h = req.get_header_value("Authorization");
  constexpr std::string_view kPrefix = "Bearer ";
  if (h.size() <= kPrefix.size() || h.compare(0, kPrefix.size(), kPrefix) != 0) return {};
  return h.substr(kPrefix.size());
}

}  // namespace

bool KeyMatches(const std::string& presented, const std::string& expected) {
  // Digests first: equal lengths, so the comparison leaks neither content nor length.
  unsigned char a[SHA256_DIGEST_LENGTH], b[SHA256_DIGEST_LENGTH];
  SHA256(reinterpret_cast<const unsigned char*>(presented.data()), presented.size(), a);
  SHA256(reinterpret_cast<const unsigned char*>(expected.data()), expected.size(), b);
  return CRYPTO_memcmp(a, b, sizeof(a)) == 0 && !expected.empty();
}

Result<std::unique_ptr<AdminHttpServer>> AdminHttpServer::Start(const AdminHttpOptions& options,
                                                                 AdminBackend* backend) {
  auto endpoint = ParseEndpoint(options.address);
  if (!endpoint.ok()) {
    return Status::InvalidArgument("bad admin address", std::string(endpoint.status().reason()));
  }
  if (options.key.empty() && !endpoint->address().is_loopback()) {
    return Status::InvalidArgument(
        "the admin API needs a key (--admin-key or EDGEPHYS_ADMIN_KEY) on a non-loopback address");
  }
  std::unique_ptr<AdminHttpServer> self(new AdminHttpServer());
  http::GateOptions gate;
  gate.address = options.address;
  gate.workers = std::max<size_t>(1, options.threads);
  gate.max_body_bytes = options.max_body_bytes;
  gate.request_deadline = options.request_deadline;
  gate.max_connections = options.max_connections;
  gate.max_per_address = options.max_per_address;
  // Liveness on the gate thread: Health() reads one atomic and never waits for the relay.
  gate.health_path = "/healthz";
  gate.health = [backend] {
    AdminReply r = backend->Health();
    return http::HealthAnswer{r.status, r.body.dump()};
  };
  self->gate_ = std::make_unique<http::HttpGate>(std::move(gate));
  httplib::Server& svr = self->gate_->routes();
  svr.set_payload_max_length(options.max_body_bytes);
  // A method the path does not take: 405 with the methods it does (Allow), else 404.
  std::vector<std::pair<std::regex, std::string>> allowed;
  for (const AdminRoute& route : AdminRoutes(*backend)) {
    const char* m = route.method == AdminRoute::Method::kGet    ? "GET"
                    : route.method == AdminRoute::Method::kPost ? "POST"
                                                                : "DELETE";
    allowed.emplace_back(std::regex(route.pattern), m);
  }
  svr.set_error_handler(httplib::Server::HandlerWithResponse(
      [allowed](const httplib::Request& req, httplib::Response& res) {
        // A route's own 404 (e.g. no such room) carries its body: only an unrouted request
        // can be a method the path does not take.
        if (res.status == 404 && res.body.empty()) {
          std::string allow;
          for (const auto& [pattern, method] : allowed) {
            if (!std::regex_match(req.path, pattern) || allow.find(method) != std::string::npos) {
              continue;
            }
            allow += (allow.empty() ? "" : ", ") + method;
          }
          const bool method_allowed =
              (", " + allow + ",").find(", " + req.method + ",") != std::string::npos;
          if (!allow.empty() && !method_allowed) {
            res.set_header("Allow", allow);
            WriteJson(res, AdminError(405, "method_not_allowed",
                                      req.method + " is not allowed here (allowed: " + allow + ")"));
            return httplib::Server::HandlerResponse::Handled;
          }
        }
        if (res.body.empty()) WriteJson(res, ErrorFor(res.status));
        return httplib::Server::HandlerResponse::Handled;
      }));
  svr.set_exception_handler([](const httplib::Request&, httplib::Response& res,
                               std::exception_ptr) {
    WriteJson(res, AdminError(500, "internal", "internal error"));
  });

  const std::string key = options.key;
  for (AdminRoute& route : AdminRoutes(*backend)) {
    httplib::Server::Handler handler = [key, route](const httplib::Request& req,
                                                    httplib::Response& res) {
      if (route.page != nullptr) {
        res.set_header("Cache-Control", "no-store");
        res.set_header("X-Content-Type-Options", "nosniff");
        res.set_header("Content-Security-Policy",
                       "default-src 'none'; script-src 'unsafe-inline'; style-src 'unsafe-inline'; "
                       "connect-src 'self'; img-src data:");
        res.set_content(route.page, route.content_type);
        return;
      }
      if (route.needs_key && !key.empty() && !KeyMatches(BearerOf(req), key)) {
        res.set_header("WWW-Authenticate", "Bearer");
        return WriteJson(res, AdminError(401, "unauthorized", "missing or wrong bearer key"));
      }
      AdminRequest request;
      for (size_t i = 1; i < req.matches.size(); ++i) request.params.push_back(req.matches[i]);
      request.query.insert(req.params.begin(), req.params.end());
      if (req.body.empty()) {
        request.body = json::object();
      } else {
        request.body = json::parse(req.body, nullptr, /*allow_exceptions=*/false);
        if (request.body.is_discarded()) {
          return WriteJson(res, AdminError(400, "bad_json", "the body is not valid JSON"));
        }
        if (!request.body.is_object()) {
          return WriteJson(res, AdminError(400, "bad_json", "the body must be a JSON object"));
        }
      }
      WriteJson(res, route.handler(request));
    };
    switch (route.method) {
      case AdminRoute::Method::kGet: svr.Get(route.pattern, handler); break;
      case AdminRoute::Method::kPost: svr.Post(route.pattern, handler); break;
      case AdminRoute::Method::kDelete: svr.Delete(route.pattern, handler); break;
    }
  }

  if (Status st = self->gate_->Start(); !st.ok()) {
    if (st.code() == StatusCode::kIoError) {
      return Status::IoError("cannot bind the admin address", std::string(st.reason()));
    }
    return st;
  }
  self->address_ = self->gate_->address();
  return self;
}

AdminHttpServer::~AdminHttpServer() { Stop(); }

void AdminHttpServer::Stop() {
  if (gate_) gate_->Stop();
}

}  // namespace edgephys::admin
