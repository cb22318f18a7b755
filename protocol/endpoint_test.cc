// ParseEndpoint: numeric addresses, host names (resolved), and errors that name their cause.
#include "protocol/endpoint.h"

#include <gtest/gtest.h>

namespace edgephys {
namespace {

TEST(ParseEndpoint, NumericAddresses) {
  auto v4 = ParseEndpoint("127.0.0.1:7777");
  ASSERT_TRUE(v4.ok());
  EXPECT_EQ(FormatEndpoint(*v4), "127.0.0.1:7777");
  auto v6 = ParseEndpoint("[::1]:9");
  ASSERT_TRUE(v6.ok());
  EXPECT_EQ(FormatEndpoint(*v6), "[::1]:9");
  auto any = ParseEndpoint(":7777");
  ASSERT_TRUE(any.ok());
  EXPECT_TRUE(any->address().is_unspecified());
}

TEST(ParseEndpoint, HostNamesAreResolved) {
  auto local = ParseEndpoint("localhost:7777");  // /etc/hosts, no network needed
  ASSERT_TRUE(local.ok()) << local.status().ToString();
  EXPECT_TRUE(local->address().is_loopback());
  EXPECT_EQ(local->port(), 7777);
}

TEST(ParseEndpoint, ErrorsNameTheirCause) {
  auto no_port = ParseEndpoint("relay.example");
  ASSERT_FALSE(no_port.ok());
  EXPECT_NE(no_port.status().ToString().find("relay.example"), std::string::npos);
  auto bad_port = ParseEndpoint("127.0.0.1:99999");
  ASSERT_FALSE(bad_port.ok());
  EXPECT_NE(bad_port.status().ToString().find("99999"), std::string::npos);
  auto unknown = ParseEndpoint("no-such-host.invalid:7777");  // .invalid never resolves
  ASSERT_FALSE(unknown.ok());
  EXPECT_NE(unknown.status().ToString().find("cannot resolve host: 'no-such-host.invalid'"),
            std::string::npos)
      << unknown.status().ToString();
}

}  // namespace
}  // namespace edgephys
