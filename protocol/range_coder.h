// Binary adaptive range coder, used by soft-body state format 11 (protocol/soft_delta_codec.h,
// docs/protocol.md §5f) to code particle residuals in fractions of a bit.
//
// Model: every binary decision has a probability cell (`RangeProb`, the probability of a 0 in
// units of 1/4096, starting at 1/2) that both sides adapt identically after each bit
// (p += (4096 - p) / 32 on a 0, p -= p / 32 on a 1), so a decision that almost always goes one
// way costs ~0.01 bit. Direct bits (EncodeDirect) use a fixed 1/2 and no cell.
//
// Stream: the usual carry-propagating range coder with 32-bit range and bytewise
// renormalisation. The encoder omits the always-zero first byte and the decoder supplies it;
// Finish() flushes four bytes and then trims trailing zero bytes, which the decoder reads back
// as zeros (bytes past the end of its input are zero). So any byte string decodes to some bit
// sequence: callers bound their loops by counts they read elsewhere and validate values.
//
// Safety: the encoder never writes outside its span (a write that does not fit sets
// overflow(); the output is then unusable). Thread-safety: plain values. Cost: O(bits), no
// allocation.
#pragma once

#include <cstddef>
#include <cstdint>
#include <span>

namespace edgephys {

using RangeProb = uint16_t;
inline constexpr int kRangeProbBits = 12;
inline constexpr RangeProb kRangeProbInit = 1u << (kRangeProbBits - 1);

class RangeEncoder {
 public:
  explicit RangeEncoder(std::span<uint8_t> out) : out_(out) {}

  void EncodeBit(RangeProb* prob, bool bit);
  // A bit with fixed probability 1/2 (no model).
  void EncodeDirect(bool bit);
  // Flushes; returns the stream's size in bytes (0 when overflow()).
  size_t Finish();

  // An upper bound of the bytes Finish() would return now.
  size_t size_bound() const { return pos_ + cache_size_ + 5; }
  bool overflow() const { return overflow_; }

 private:
  void ShiftLow();
  void Put(uint8_t byte);

  std::span<uint8_t> out_;
  size_t pos_ = 0;
  uint64_t low_ = 0;
  uint32_t range_ = 0xFFFFFFFFu;
  uint8_t cache_ = 0;
  uint64_t cache_size_ = 1;
  bool first_ = true;  // the first byte out is always 0 and is omitted
  bool overflow_ = false;
};

class RangeDecoder {
 public:
  explicit RangeDecoder(std::span<const uint8_t> in);

  bool DecodeBit(RangeProb* prob);
  bool DecodeDirect();

 private:
  uint8_t Next() { return pos_ < in_.size() ? in_[pos_++] : (++pos_, uint8_t{0}); }
  void Normalize();

  std::span<const uint8_t> in_;
  size_t pos_ = 0;
  uint32_t range_ = 0xFFFFFFFFu;
  uint32_t code_ = 0;
};

}  // namespace edgephys
