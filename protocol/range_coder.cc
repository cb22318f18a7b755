#include "protocol/range_coder.h"

namespace edgephys {
namespace {
constexpr uint32_t kTop = 1u << 24;
constexpr int kAdaptShift = 5;
constexpr uint32_t kProbOne = 1u << kRangeProbBits;
}  // namespace

void RangeEncoder::Put(uint8_t byte) {
  if (first_) {  // always 0: the decoder supplies it
    first_ = false;
    return;
  }
  if (pos_ >= out_.size()) {
    overflow_ = true;
    return;
  }
  out_[pos_++] = byte;
}

void RangeEncoder::ShiftLow() {
  if (static_cast<uint32_t>(low_) < 0xFF000000u || (low_ >> 32) != 0) {
    const uint8_t carry = static_cast<uint8_t>(low_ >> 32);
    uint8_t pending = cache_;
    do {
      Put(static_cast<uint8_t>(pending + carry));
      pending = 0xFF;
    } while (--cache_size_ != 0);
    cache_ = static_cast<uint8_t>(low_ >> 24);
  }
  ++cache_size_;
  low_ = (low_ & 0x00FFFFFFu) << 8;
}

void RangeEncoder::EncodeBit(RangeProb* prob, bool bit) {
  const uint32_t bound = (range_ >> kRangeProbBits) * *prob;
  if (!bit) {
    range_ = bound;
    *prob = static_cast<RangeProb>(*prob + ((kProbOne - *prob) >> kAdaptShift));
  } else {
    low_ += bound;
    range_ -= bound;
    *prob = static_cast<RangeProb>(*prob - (*prob >> kAdaptShift));
  }
  while (range_ < kTop) {
    range_ <<= 8;
    ShiftLow();
  }
}

void RangeEncoder::EncodeDirect(bool bit) {
  range_ >>= 1;
  if (bit) low_ += range_;
  while (range_ < kTop) {
    range_ <<= 8;
    ShiftLow();
  }
}

size_t RangeEncoder::Finish() {
  for (int i = 0; i < 5; ++i) ShiftLow();
  if (overflow_) return 0;
  while (pos_ > 0 && out_[pos_ - 1] == 0) --pos_;  // the decoder reads zeros past the end
  return pos_;
}

RangeDecoder::RangeDecoder(std::span<const uint8_t> in) : in_(in) {
  for (int i = 0; i < 4; ++i) code_ = (code_ << 8) | Next();
}

void RangeDecoder::Normalize() {
  while (range_ < kTop) {
    range_ <<= 8;
    code_ = (code_ << 8) | Next();
  }
}

bool RangeDecoder::DecodeBit(RangeProb* prob) {
  const uint32_t bound = (range_ >> kRangeProbBits) * *prob;
  bool bit;
  if (code_ < bound) {
    range_ = bound;
    *prob = static_cast<RangeProb>(*prob + ((kProbOne - *prob) >> kAdaptShift));
    bit = false;
  } else {
    code_ -= bound;
    range_ -= bound;
    *prob = static_cast<RangeProb>(*prob - (*prob >> kAdaptShift));
    bit = true;
  }
  Normalize();
  return bit;
}

bool RangeDecoder::DecodeDirect() {
  range_ >>= 1;
  bool bit = false;
  if (code_ >= range_) {
    code_ -= range_;
    bit = true;
  }
  Normalize();
  return bit;
}

}  // namespace edgephys
