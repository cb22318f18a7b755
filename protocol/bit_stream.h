// Bit-level writer and reader over caller-owned byte spans, used by state format 2
// (docs/protocol.md §5b).
//
// Bit order: bits are packed LSB-first: the first bit written is bit 0 of byte 0, the ninth is
// bit 0 of byte 1. A multi-bit field of n bits is written low bit first (so it reads back as
// the same integer). Bytes are zeroed when first touched, so a finished stream is padded with
// zero bits up to the next byte boundary.
//
// Residual code: signed residuals r are zigzag-mapped (0, -1, 1, -2, 2 ... -> 0, 1, 2, 3, 4 ...)
// and written with an Exp-Golomb code of order k: u + 2^k has n = bit_width(u + 2^k) bits;
// write n - k - 1 zero bits, one 1 bit, then the low n - 1 bits of u + 2^k. Cost
// 2 * (n - k) - 1 + k bits. k adapts per packet (the format-2 encoder picks it from the
// residuals it has recently coded). DeltaEncoderStats counts what a per-packet fixed bit width
// would have cost instead.
//
// Safety: neither class ever touches memory outside its span. A write that does not fit fails
// (returns false, nothing written) and sets overflow(); a read past the end fails (returns
// false, position unchanged).
// Thread-safety: plain values over caller memory. Cost: O(bits), no allocation.
#pragma once

#include <cstddef>
#include <cstdint>
#include <span>

namespace edgephys {

inline uint32_t ZigZag(int32_t v) {
  return (static_cast<uint32_t>(v) << 1) ^ static_cast<uint32_t>(-(static_cast<int64_t>(v) < 0));
}
inline int32_t UnZigZag(uint32_t u) { return static_cast<int32_t>((u >> 1) ^ (0u - (u & 1u))); }

// Bits of the order-k Exp-Golomb code of u (k in 0..31).
int ExpGolombBits(uint32_t u, int k);

class BitWriter {
 public:
  BitWriter() = default;
  explicit BitWriter(std::span<uint8_t> out) : out_(out) {}

  // Writes the low `bits` bits of `value` (bits in 0..64). False if it does not fit.
  bool WriteBits(uint64_t value, int bits);
  bool WriteBit(bool bit) { return WriteBits(bit ? 1 : 0, 1); }
  // Order-k Exp-Golomb code of u (k in 0..31).
  bool WriteExpGolomb(uint32_t u, int k);
  // Zigzag + order-k Exp-Golomb.
  bool WriteSigned(int32_t v, int k) { return WriteExpGolomb(ZigZag(v), k); }

  // Appends the first `bits` bits of `src` (a stream written LSB-first, e.g. by another
  // BitWriter) at the current position: records precomputed once and copied into many
  // streams (format 9). False if it does not fit (nothing written) or `src` is too short.
  bool AppendBits(std::span<const uint8_t> src, size_t bits);

  size_t bit_position() const { return bit_pos_; }
  // Bytes touched so far (ceil(bits / 8)).
  size_t byte_size() const { return (bit_pos_ + 7) / 8; }
  size_t capacity_bits() const { return out_.size() * 8; }
  bool overflow() const { return overflow_; }
  // Moves back to an earlier bit position (discarding later bits) and clears overflow().
  void Rewind(size_t bit_position);

 private:
  std::span<uint8_t> out_;
  size_t bit_pos_ = 0;
  bool overflow_ = false;
};

class BitReader {
 public:
  explicit BitReader(std::span<const uint8_t> in) : in_(in) {}

  // Reads `bits` bits (0..64) into *value. False (position unchanged) past the end.
  bool ReadBits(int bits, uint64_t* value);
  bool ReadBit(bool* bit);
  // False on overrun or a code longer than 32 bits of value (malformed input).
  bool ReadExpGolomb(int k, uint32_t* u);
  bool ReadSigned(int k, int32_t* v);

  size_t bit_position() const { return bit_pos_; }
  size_t remaining_bits() const { return in_.size() * 8 - bit_pos_; }

 private:
  std::span<const uint8_t> in_;
  size_t bit_pos_ = 0;
};

}  // namespace edgephys
