#include "protocol/packet.h"

#include <gtest/gtest.h>

#include <array>
#include <cctype>
#include <set>
#include <string>
#include <vector>

#include "protocol/byte_io.h"
#include "protocol/sequence.h"

namespace edgephys {
namespace {

std::vector<uint8_t> Prefix(PacketType type, uint32_t id) {
  std::vector<uint8_t> out(kPacketPrefixSize);
  EXPECT_EQ(WritePacketPrefix(type, id, out), kPacketPrefixSize);
  return out;
}

TEST(PacketPrefixTest, WritesLittleEndianLayout) {
  std::vector<uint8_t> bytes = Prefix(PacketType::kData, 0x04030201u);
  std::vector<uint8_t> expected = {'E', 'P', 'H', 'Y', kProtocolVersion, 16, 1, 2, 3, 4};
  EXPECT_EQ(bytes, expected);
}

TEST(PacketPrefixTest, RoundTripsEveryType) {
  for (PacketType type :
       {PacketType::kHello, PacketType::kChallenge, PacketType::kConnect, PacketType::kAccept,
        PacketType::kReject, PacketType::kData, PacketType::kDisconnect}) {
    std::vector<uint8_t> bytes = Prefix(type, 0xDEADBEEFu);
    bytes.push_back(0);  // body bytes do not matter to the prefix
    PacketPrefix prefix{};
    DropReason reason = DropReason::kCount;
    ASSERT_TRUE(ParsePacketPrefix(bytes, &prefix, &reason));
    EXPECT_EQ(prefix.type, type);
    EXPECT_EQ(prefix.connection_id, 0xDEADBEEFu);
  }
}

TEST(PacketPrefixTest, RejectsWithReason) {
  PacketPrefix prefix{};
  DropReason reason{};
  std::vector<uint8_t> good = Prefix(PacketType::kData, 1);

  for (size_t size = 0; size < kPacketPrefixSize; ++size) {
    EXPECT_FALSE(ParsePacketPrefix(std::span(good.data(), size), &prefix, &reason));
    EXPECT_EQ(reason, DropReason::kTooShort);
  }
  std::vector<uint8_t> big = good;
  big.resize(kMaxPacketSize + 1);
  EXPECT_FALSE(ParsePacketPrefix(big, &prefix, &reason));
  EXPECT_EQ(reason, DropReason::kTooLarge);
  big.resize(kMaxPacketSize);
  EXPECT_TRUE(ParsePacketPrefix(big, &prefix, &reason));

  std::vector<uint8_t> bad = good;
  bad[0] ^= 1;
  EXPECT_FALSE(ParsePacketPrefix(bad, &prefix, &reason));
  EXPECT_EQ(reason, DropReason::kBadProtocolId);
  bad = good;
  bad[4] = kProtocolVersion + 1;
  EXPECT_FALSE(ParsePacketPrefix(bad, &prefix, &reason));
  EXPECT_EQ(reason, DropReason::kBadVersion);
  for (int type : {0, 6, 15, 18, 255}) {
    bad = good;
    bad[5] = static_cast<uint8_t>(type);
    EXPECT_FALSE(ParsePacketPrefix(bad, &prefix, &reason));
    EXPECT_EQ(reason, DropReason::kUnknownType);
  }
}

TEST(PacketPrefixTest, WriteRefusesShortBuffer) {
  std::array<uint8_t, kPacketPrefixSize - 1> small{};
  EXPECT_EQ(WritePacketPrefix(PacketType::kData, 1, small), 0u);
}

TEST(DropReasonNameTest, EveryReasonHasAUniqueSnakeCaseName) {
  std::set<std::string> names;
  for (int i = 0; i < static_cast<int>(DropReason::kCount); ++i) {
    std::string name(DropReasonName(static_cast<DropReason>(i)));
    EXPECT_NE(name, "unknown") << i;
    EXPECT_FALSE(name.empty());
    for (char c : name) {
      EXPECT_TRUE(std::islower(static_cast<unsigned char>(c)) || c == '_') << name;
    }
    EXPECT_TRUE(names.insert(name).second) << name;
  }
  EXPECT_EQ(DropReasonName(DropReason::kTooShort), "too_short");
  EXPECT_EQ(DropReasonName(DropReason::kBadProtocolId), "bad_protocol_id");
  EXPECT_EQ(DropReasonName(DropReason::kNotOwner), "not_owner");
  EXPECT_EQ(DropReasonName(DropReason::kCount), "unknown");
}

TEST(SequenceTest, ComparesAcrossWrapAround) {
  EXPECT_TRUE(SequenceGreater(1, 0));
  EXPECT_FALSE(SequenceGreater(0, 0));
  EXPECT_TRUE(SequenceGreater(0, 65535));
  EXPECT_TRUE(SequenceGreater(10, 65530));
  EXPECT_FALSE(SequenceGreater(65530, 10));
  EXPECT_EQ(SequenceDiff(3, 65533), 6);
  EXPECT_EQ(SequenceDiff(65533, 3), -6);
  EXPECT_TRUE(SequenceGreater(32767, 0));
  EXPECT_FALSE(SequenceGreater(32768, 0));  // exactly half way counts as older
}

TEST(ByteIoTest, ReadsWhatWasWrittenAndNeverOverruns) {
  std::array<uint8_t, 7> buffer{};
  ByteWriter writer(buffer);
  EXPECT_TRUE(writer.WriteU8(0xAB));
  EXPECT_TRUE(writer.WriteU16(0x1234));
  EXPECT_TRUE(writer.WriteU32(0xCAFEBABEu));
  EXPECT_FALSE(writer.WriteU8(1));
  EXPECT_EQ(buffer[1], 0x34);
  EXPECT_EQ(buffer[2], 0x12);
  ByteReader reader(buffer);
  uint8_t a = 0;
  uint16_t b = 0;
  uint32_t c = 0;
  EXPECT_TRUE(reader.ReadU8(&a));
  EXPECT_TRUE(reader.ReadU16(&b));
  EXPECT_FALSE(reader.ReadBytes(5, nullptr));
  EXPECT_TRUE(reader.ReadU32(&c));
  EXPECT_EQ(a, 0xAB);
  EXPECT_EQ(b, 0x1234);
  EXPECT_EQ(c, 0xCAFEBABEu);
  EXPECT_FALSE(reader.ReadU16(&b));
  EXPECT_EQ(reader.remaining(), 0u);
}

}  // namespace
}  // namespace edgephys
