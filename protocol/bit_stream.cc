#include "protocol/bit_stream.h"

#include <bit>
#include <cstring>

namespace edgephys {

int ExpGolombBits(uint32_t u, int k) {
  const uint64_t v = static_cast<uint64_t>(u) + (uint64_t{1} << k);
  const int n = std::bit_width(v);
  return 2 * (n - k) - 1 + k;
}

bool BitWriter::WriteBits(uint64_t value, int bits) {
  if (bits <= 0) return true;
  if (bits > 64 || bit_pos_ + static_cast<size_t>(bits) > capacity_bits()) {
    overflow_ = true;
    return false;
  }
  if (bits < 64) value &= (uint64_t{1} << bits) - 1;
  if constexpr (std::endian::native == std::endian::little) {
    // Fast path: one 64-bit read-modify-write when 8 bytes are available. Bytes past the
    // written bits are zeroed, as the byte loop would when first touching them.
    const size_t byte = bit_pos_ >> 3;
    const int offset = static_cast<int>(bit_pos_ & 7);
    if (bits <= 56 && byte + 8 <= out_.size()) {
      uint64_t word;
      std::memcpy(&word, out_.data() + byte, 8);
      word = (word & ((uint64_t{1} << offset) - 1)) | (value << offset);
      std::memcpy(out_.data() + byte, &word, 8);
      bit_pos_ += static_cast<size_t>(bits);
      return true;
    }
  }
  while (bits > 0) {
    const size_t byte = bit_pos_ >> 3;
    const int offset = static_cast<int>(bit_pos_ & 7);
    if (offset == 0) out_[byte] = 0;
    const int take = bits < 8 - offset ? bits : 8 - offset;
    const uint64_t chunk = value & ((uint64_t{1} << take) - 1);
    out_[byte] = static_cast<uint8_t>(out_[byte] | (chunk << offset));
    value >>= take;
    bits -= take;
    bit_pos_ += static_cast<size_t>(take);
  }
  return true;
}

bool BitWriter::AppendBits(std::span<const uint8_t> src, size_t bits) {
  if (bits > src.size() * 8) return false;
  if (bit_pos_ + bits > capacity_bits()) {
    overflow_ = true;
    return false;
  }
  size_t byte = 0;
  while (bits > 0) {
    // Up to 56 bits a step from whole source bytes (the source starts at a byte boundary).
    const size_t n = bits < 56 ? bits : 56;
    const size_t nbytes = (n + 7) / 8;
    uint64_t v = 0;
    for (size_t i = 0; i < nbytes; ++i) v |= static_cast<uint64_t>(src[byte + i]) << (8 * i);
    WriteBits(v, static_cast<int>(n));
    byte += nbytes;
    bits -= n;
  }
  return true;
}

bool BitWriter::WriteExpGolomb(uint32_t u, int k) {
  const uint64_t v = static_cast<uint64_t>(u) + (uint64_t{1} << k);
  const int n = std::bit_width(v);
  const int zeros = n - k - 1;
  if (bit_pos_ + static_cast<size_t>(zeros + n) > capacity_bits()) {
    overflow_ = true;
    return false;
  }
  WriteBits(0, zeros);
  WriteBits(1, 1);
  WriteBits(v, n - 1);  // low n-1 bits (the leading 1 is implied by the marker above)
  return true;
}

void BitWriter::Rewind(size_t bit_position) {
  if (bit_position > bit_pos_) return;
  bit_pos_ = bit_position;
  overflow_ = false;
  const int offset = static_cast<int>(bit_pos_ & 7);
  if (offset != 0) {
    out_[bit_pos_ >> 3] = static_cast<uint8_t>(out_[bit_pos_ >> 3] & ((1u << offset) - 1));
  }
}

bool BitReader::ReadBits(int bits, uint64_t* value) {
  if (bits < 0 || bits > 64 || static_cast<size_t>(bits) > remaining_bits()) return false;
  uint64_t v = 0;
  int got = 0;
  size_t pos = bit_pos_;
  while (got < bits) {
    const size_t byte = pos >> 3;
    const int offset = static_cast<int>(pos & 7);
    const int take = bits - got < 8 - offset ? bits - got : 8 - offset;
    const uint64_t chunk = (static_cast<uint64_t>(in_[byte]) >> offset) & ((1u << take) - 1);
    v |= chunk << got;
    got += take;
    pos += static_cast<size_t>(take);
  }
  bit_pos_ = pos;
  *value = v;
  return true;
}

bool BitReader::ReadBit(bool* bit) {
  uint64_t v;
  if (!ReadBits(1, &v)) return false;
  *bit = v != 0;
  return true;
}

bool BitReader::ReadExpGolomb(int k, uint32_t* u) {
  const size_t start = bit_pos_;
  int zeros = 0;
  for (;;) {
    uint64_t b;
    if (!ReadBits(1, &b)) {
      bit_pos_ = start;
      return false;
    }
    if (b != 0) break;
    if (++zeros + k > 32) {
      bit_pos_ = start;
      return false;
    }
  }
  const int n = zeros + k + 1;  // bits of u + 2^k including the leading 1
  uint64_t low = 0;
  if (!ReadBits(n - 1, &low)) {
    bit_pos_ = start;
    return false;
  }
  const uint64_t v = (uint64_t{1} << (n - 1)) | low;
  const uint64_t value = v - (uint64_t{1} << k);
  if (value > UINT32_MAX) {
    bit_pos_ = start;
    return false;
  }
  *u = static_cast<uint32_t>(value);
  return true;
}

bool BitReader::ReadSigned(int k, int32_t* v) {
  uint32_t u;
  if (!ReadExpGolomb(k, &u)) return false;
  *v = UnZigZag(u);
  return true;
}

}  // namespace edgephys
