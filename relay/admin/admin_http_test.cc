// The HTTP front over a recording backend: the key, the body limit, JSON errors, routing and
// parameter checks. The real relay behind it is tested in tests/admin/admin_api_test.sh.
#include "relay/admin/admin_http.h"
#include "relay/admin/testing/loopback_admin.h"

#include <gtest/gtest.h>
#include <httplib.h>

#include <arpa/inet.h>
#include <netinet/in.h>
#include <sys/socket.h>
#include <unistd.h>

#include <mutex>

namespace edgephys::admin {
namespace {

using nlohmann::json;

class RecordingBackend final : public AdminBackend {
 public:
  AdminReply ListRooms() override { return Note("list", {{"rooms", json::array()}}); }
  AdminReply GetRoom(const std::string& id) override { return Note("get " + id, {}); }
  AdminReply GetRoomMap(const std::string& id, size_t limit) override {
    return Note("map " + id + " " + std::to_string(limit), {});
  }
  AdminReply CreateRoom(const json& request) override { return Note("create " + request.dump(), {}); }
  AdminReply CloseRoom(const std::string& id, const std::string& reason) override {
    return Note("close " + id + " " + reason, {});
  }
  AdminReply Kick(const std::string& room, uint32_t player, const std::string& reason) override {
    return Note("kick " + room + " " + std::to_string(player) + " " + reason, {});
  }
  AdminReply Drain(double deadline_s) override {
    return Note("drain " + std::to_string(static_cast<int>(deadline_s)), {});
  }
  AdminReply Health() override { return Note("health", {{"status", "ok"}}); }
  AdminReply Ready() override { return Note("ready", {{"ready", true}}); }

  std::string last() {
    std::lock_guard lock(mu_);
    return last_;
  }

 private:
  AdminReply Note(std::string what, json body) {
    std::lock_guard lock(mu_);
    last_ = std::move(what);
    AdminReply r;
    r.body = std::move(body);
    return r;
  }
  std::mutex mu_;
  std::string last_;
};

class AdminHttpTest : public ::testing::Test {
 protected:
  void SetUp() override {
    AdminHttpOptions options;
    options.key = "s3cret";
    options.max_body_bytes = 1024;
    server_ = testing::StartLoopbackAdmin(options, &backend_);
    ASSERT_NE(server_, nullptr);
    client_ = std::make_unique<httplib::Client>("127.0.0.1", testing::AdminPort(*server_));
    client_->set_connection_timeout(5);
    client_->set_read_timeout(5);
  }
  httplib::Headers Auth(const std::string& key = "s3cret") {
    return {{"Authorization", "Bearer " + key}};
  }
  static std::string Code(const httplib::Result& r) {
    auto body = json::parse(r->body, nullptr, false);
    if (body.is_discarded() || !body.contains("error")) return "(no error: " + r->body + ")";
    return body["error"]["code"];
  }

  RecordingBackend backend_;
  std::unique_ptr<AdminHttpServer> server_;
  std::unique_ptr<httplib::Client> client_;
};

TEST_F(AdminHttpTest, KeyIsRequiredAndChecked) {
  auto none = client_->Get("/v1/rooms");
  ASSERT_TRUE(none);
  EXPECT_EQ(none->status, 401);
  EXPECT_EQ(Code(none), "unauthorized");
  auto wrong = client_->Get("/v1/rooms", Auth("s3cret2"));
  EXPECT_EQ(wrong->status, 401);
  auto prefix = client_->Get("/v1/rooms", Auth("s3cre"));
  EXPECT_EQ(prefix->status, 401);
  auto basic = client_->Get("/v1/rooms", {{"Authorization", "Basic s3cret"}});
  EXPECT_EQ(basic->status, 401);
  EXPECT_EQ(backend_.last(), "");
  auto ok = client_->Get("/v1/rooms", Auth());
  EXPECT_EQ(ok->status, 200);
  EXPECT_EQ(ok->get_header_value("Content-Type"), "application/json");
  EXPECT_EQ(backend_.last(), "list");
}

TEST_F(AdminHttpTest, ProbesAndMonitorNeedNoKey) {
  EXPECT_EQ(client_->Get("/healthz")->status, 200);
  EXPECT_EQ(client_->Get("/readyz")->status, 200);
  auto page = client_->Get("/monitor");
  ASSERT_TRUE(page);
  EXPECT_EQ(page->status, 200);
  EXPECT_NE(page->body.find("<title>edgephys relay monitor</title>"), std::string::npos);
  EXPECT_EQ(page->body.find("https://"), std::string::npos) << "the page must be self-contained";
}

TEST_F(AdminHttpTest, BadBodiesGetJsonErrors) {
  auto bad = client_->Post("/v1/rooms", Auth(), "{\"id\": ", "application/json");
  EXPECT_EQ(bad->status, 400);
  EXPECT_EQ(Code(bad), "bad_json");
  auto array = client_->Post("/v1/rooms", Auth(), "[1, 2]", "application/json");
  EXPECT_EQ(array->status, 400);
  EXPECT_EQ(Code(array), "bad_json");
  auto deep = client_->Post("/v1/rooms", Auth(), std::string(1000, '['), "application/json");
  EXPECT_EQ(deep->status, 400);
  auto binary = client_->Post("/v1/rooms", Auth(), std::string("\xff\xfe\x00\x01", 4),
                              "application/json");
  EXPECT_EQ(binary->status, 400);
  auto big = client_->Post("/v1/rooms", Auth(), "{\"id\": \"" + std::string(4000, 'a') + "\"}",
                           "application/json");
  ASSERT_TRUE(big);
  EXPECT_EQ(big->status, 413);
  EXPECT_EQ(Code(big), "body_too_large");
  auto good = client_->Post("/v1/rooms", Auth(), R"({"id": "a"})", "application/json");
  EXPECT_EQ(good->status, 200);
  EXPECT_EQ(backend_.last(), R"(create {"id":"a"})");
}

TEST_F(AdminHttpTest, RoutesAndParameters) {
  auto unknown = client_->Get("/v1/nothing", Auth());
  EXPECT_EQ(unknown->status, 404);
  EXPECT_EQ(Code(unknown), "not_found");
  EXPECT_EQ(client_->Get("/v1/rooms/lob%20by", Auth())->status, 200);
  EXPECT_EQ(backend_.last(), "get lob by");
  EXPECT_EQ(client_->Delete("/v1/rooms/x", Auth())->status, 200);
  EXPECT_EQ(backend_.last(), "close x the room was closed by the operator");
  auto kick = client_->Post("/v1/rooms/x/members/7/kick", Auth(), R"({"reason": "spam"})",
                            "application/json");
  EXPECT_EQ(kick->status, 200);
  EXPECT_EQ(backend_.last(), "kick x 7 spam");
  for (const char* player : {"0", "-1", "abc", "4294967296", "99999999999"}) {
    auto r = client_->Post(std::string("/v1/rooms/x/members/") + player + "/kick", Auth(), "{}",
                           "application/json");
    EXPECT_EQ(r->status, 400) << player;
    EXPECT_EQ(Code(r), "invalid_request") << player;
  }
  auto long_reason = client_->Post("/v1/rooms/x/members/7/kick", Auth(),
                                   "{\"reason\": \"" + std::string(300, 'r') + "\"}",
                                   "application/json");
  EXPECT_EQ(long_reason->status, 400);
  auto extra = client_->Post("/v1/rooms/x/members/7/kick", Auth(), R"({"why": "x"})",
                             "application/json");
  EXPECT_EQ(extra->status, 400);
  EXPECT_EQ(client_->Post("/v1/drain", Auth(), R"({"deadline_s": -5})", "application/json")->status,
            400);
  EXPECT_EQ(client_->Post("/v1/drain", Auth(), R"({"deadline_s": "soon"})", "application/json")->status,
            400);
  EXPECT_EQ(client_->Post("/v1/drain", Auth(), R"({"deadline_s": 30})", "application/json")->status,
            200);
  EXPECT_EQ(backend_.last(), "drain 30");
}

// What `curl -X POST` sends: no body and no Content-Length; the key check and the handler
// must see it (the body is optional), not "malformed HTTP request".
TEST_F(AdminHttpTest, PostWithoutBodyReachesTheKeyCheck) {
  const int port = testing::AdminPort(*server_);
  auto raw = [&](const std::string& request) {
    int fd = ::socket(AF_INET, SOCK_STREAM, 0);
    sockaddr_in to{};
    to.sin_family = AF_INET;
    to.sin_port = htons(static_cast<uint16_t>(port));
    inet_pton(AF_INET, "127.0.0.1", &to.sin_addr);
    EXPECT_EQ(::connect(fd, reinterpret_cast<sockaddr*>(&to), sizeof(to)), 0);
    (void)::send(fd, request.data(), request.size(), MSG_NOSIGNAL);
    std::string out;
    char buf[4096];
    timeval tv{3, 0};
    setsockopt(fd, SOL_SOCKET, SO_RCVTIMEO, &tv, sizeof(tv));
    for (ssize_t n; (n = ::recv(fd, buf, sizeof(buf), 0)) > 0;) out.append(buf, n);
    ::close(fd);
    return out;
  };
  std::string no_key = raw("POST /v1/rooms/x/members/7/kick HTTP/1.1\r\nHost: a\r\n\r\n");
  EXPECT_EQ(no_key.rfind("HTTP/1.1 401", 0), 0u) << no_key;
  std::string kick = raw("POST /v1/rooms/x/members/7/kick HTTP/1.1\r\nHost: a\r\n"
                         "Authorization: Bearer s3cret\r\n\r\n");
  EXPECT_EQ(kick.rfind("HTTP/1.1 200", 0), 0u) << kick;
  EXPECT_EQ(backend_.last(), "kick x 7 kicked by the operator");
  std::string drain = raw("POST /v1/drain HTTP/1.1\r\nAuthorization: Bearer s3cret\r\n\r\n");
  EXPECT_EQ(drain.rfind("HTTP/1.1 200", 0), 0u) << drain;
  EXPECT_EQ(backend_.last(), "drain 300");
  // A key with trailing whitespace or a NUL is not the key.
  std::string space = raw("GET /v1/rooms HTTP/1.1\r\nAuthorization: Bearer s3cret \r\n\r\n");
  EXPECT_EQ(space.rfind("HTTP/1.1 400", 0), 0u) << space;
  std::string nul = "GET /v1/rooms HTTP/1.1\r\nAuthorization: Bearer s3cret";
  nul.push_back('\0');
  std::string with_nul = raw(nul + "\r\n\r\n");
  EXPECT_EQ(with_nul.rfind("HTTP/1.1 400", 0), 0u) << with_nul;
  std::string many = "GET /v1/rooms HTTP/1.1\r\nAuthorization: Bearer s3cret\r\n";
  for (int i = 0; i < 150; ++i) many += "X-" + std::to_string(i) + ": 1\r\n";
  std::string too_many = raw(many + "\r\n");
  EXPECT_EQ(too_many.rfind("HTTP/1.1 431", 0), 0u) << too_many;
  EXPECT_NE(backend_.last(), "list");
}

TEST_F(AdminHttpTest, WrongMethodGets405WithAllow) {
  auto put = client_->Put("/v1/rooms/x", Auth(), "{}", "application/json");
  ASSERT_TRUE(put);
  EXPECT_EQ(put->status, 405);
  EXPECT_EQ(Code(put), "method_not_allowed");
  EXPECT_EQ(put->get_header_value("Allow"), "GET, DELETE");
  auto post_health = client_->Post("/healthz", "", "application/json");
  EXPECT_EQ(post_health->status, 405);
  EXPECT_EQ(post_health->get_header_value("Allow"), "GET");
  EXPECT_EQ(client_->Put("/v1/none", Auth(), "{}", "application/json")->status, 404);
}

// The map route (GET /v1/rooms/{id}/map): the key, the method, the room id and the limit are
// checked before the backend is asked; each refusal is a JSON error naming its cause.
TEST_F(AdminHttpTest, MapRouteRefusesBadInputWithJsonErrors) {
  auto no_key = client_->Get("/v1/rooms/x/map");
  ASSERT_TRUE(no_key);
  EXPECT_EQ(no_key->status, 401);
  EXPECT_EQ(Code(no_key), "unauthorized");
  EXPECT_EQ(client_->Get("/v1/rooms/x/map", Auth("wrong"))->status, 401);
  EXPECT_EQ(backend_.last(), "");
  for (auto* call : {+[](httplib::Client& c, const httplib::Headers& h) {
                       return c.Post("/v1/rooms/x/map", h, "{}", "application/json");
                     },
                     +[](httplib::Client& c, const httplib::Headers& h) {
                       return c.Delete("/v1/rooms/x/map", h);
                     }}) {
    auto r = call(*client_, Auth());
    ASSERT_TRUE(r);
    EXPECT_EQ(r->status, 405);
    EXPECT_EQ(Code(r), "method_not_allowed");
    EXPECT_EQ(r->get_header_value("Allow"), "GET");
  }
  EXPECT_EQ(backend_.last(), "");

  auto ok = client_->Get("/v1/rooms/x/map", Auth());
  EXPECT_EQ(ok->status, 200);
  EXPECT_EQ(backend_.last(), "map x 2000");
  EXPECT_EQ(client_->Get("/v1/rooms/x/map?limit=5", Auth())->status, 200);
  EXPECT_EQ(backend_.last(), "map x 5");

  // A 65-byte id is refused on every room route; 64 bytes is a room id.
  const std::string long_id(65, 'r');
  for (const std::string& path : {"/v1/rooms/" + long_id + "/map", "/v1/rooms/" + long_id}) {
    auto r = client_->Get(path, Auth());
    EXPECT_EQ(r->status, 400) << path;
    EXPECT_EQ(Code(r), "invalid_request") << path;
    EXPECT_NE(r->body.find("1..64 bytes"), std::string::npos) << r->body;
  }
  EXPECT_EQ(client_->Delete("/v1/rooms/" + long_id, Auth())->status, 400);
  EXPECT_EQ(client_->Post("/v1/rooms/" + long_id + "/members/7/kick", Auth(), "{}",
                          "application/json")->status, 400);
  EXPECT_EQ(backend_.last(), "map x 5");
  EXPECT_EQ(client_->Get("/v1/rooms/" + std::string(64, 'r') + "/map", Auth())->status, 200);
  EXPECT_EQ(backend_.last(), "map " + std::string(64, 'r') + " 2000");

  // Odd bytes reach the backend decoded (join tokens may name rooms with any bytes), and the
  // answer stays JSON.
  auto odd = client_->Get("/v1/rooms/a%20%C3%A9%FF%01b/map", Auth());
  EXPECT_EQ(odd->status, 200);
  EXPECT_EQ(backend_.last(), std::string("map a \xC3\xA9\xFF\x01") + "b 2000");

  for (const char* query : {"limit=0", "limit=-1", "limit=abc", "limit=2001", "limit=1e3",
                            "limit=", "limit=99999999999", "limit=5&limit=6", "level=3"}) {
    auto r = client_->Get(std::string("/v1/rooms/x/map?") + query, Auth());
    ASSERT_TRUE(r) << query;
    EXPECT_EQ(r->status, 400) << query;
    EXPECT_EQ(Code(r), "invalid_request") << query;
  }
  EXPECT_EQ(backend_.last(), std::string("map a \xC3\xA9\xFF\x01") + "b 2000");
}

TEST(AdminHttpStartTest, RefusesAnOpenAddressWithoutAKey) {
  RecordingBackend backend;
  AdminHttpOptions options;
  options.address = "0.0.0.0:0";
  auto refused = AdminHttpServer::Start(options, &backend);
  ASSERT_FALSE(refused.ok());
  EXPECT_EQ(refused.status().code(), StatusCode::kInvalidArgument);
  options.address = "not an address";
  EXPECT_FALSE(AdminHttpServer::Start(options, &backend).ok());
  options.address = "0.0.0.0:0";
  options.key = "k";
  auto started = AdminHttpServer::Start(options, &backend);
  ASSERT_TRUE(started.ok()) << started.status().ToString();
  (*started)->Stop();
  (*started)->Stop();  // idempotent
}

TEST_F(AdminHttpTest, ASecondServerCannotShareThePort) {
  // Two relays on one admin port would split its requests between them (SO_REUSEPORT).
  RecordingBackend other;
  AdminHttpOptions options;
  options.address = server_->address();
  auto second = AdminHttpServer::Start(options, &other);
  ASSERT_FALSE(second.ok());
  EXPECT_EQ(second.status().code(), StatusCode::kIoError);
}

TEST(AdminHttpStartTest, KeyMatchesIsExact) {
  EXPECT_TRUE(KeyMatches("abc", "abc"));
  EXPECT_FALSE(KeyMatches("abd", "abc"));
  EXPECT_FALSE(KeyMatches("ab", "abc"));
  EXPECT_FALSE(KeyMatches("", ""));  // an empty key never matches
}

}  // namespace
}  // namespace edgephys::admin
