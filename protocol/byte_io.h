// Little-endian byte readers and writers for the wire format. Every multi-byte field is
// written byte by byte (no memcpy of integers or structs), so the encoding does not depend on
// the host's endianness or alignment.
//
// ByteReader and ByteWriter never read or write outside their span: a read or write that does
// not fit fails (returns false) and leaves the position unchanged.
// Thread-safety: plain values over caller-owned memory. Cost: O(bytes), no allocation.
#pragma once

#include <cstddef>
#include <cstdint>
#include <cstring>
#include <span>

namespace edgephys {

inline void StoreU16LE(uint8_t* out, uint16_t v) {
  out[0] = static_cast<uint8_t>(v);
  out[1] = static_cast<uint8_t>(v >> 8);
}

inline void StoreU32LE(uint8_t* out, uint32_t v) {
  out[0] = static_cast<uint8_t>(v);
  out[1] = static_cast<uint8_t>(v >> 8);
  out[2] = static_cast<uint8_t>(v >> 16);
  out[3] = static_cast<uint8_t>(v >> 24);
}

inline uint16_t LoadU16LE(const uint8_t* in) { return static_cast<uint16_t>(in[0] | (in[1] << 8)); }

inline uint32_t LoadU32LE(const uint8_t* in) {
  return static_cast<uint32_t>(in[0]) | (static_cast<uint32_t>(in[1]) << 8) |
         (static_cast<uint32_t>(in[2]) << 16) | (static_cast<uint32_t>(in[3]) << 24);
}

inline void StoreU64LE(uint8_t* out, uint64_t v) {
  for (int i = 0; i < 8; ++i) out[i] = static_cast<uint8_t>(v >> (8 * i));
}

inline uint64_t LoadU64LE(const uint8_t* in) {
  uint64_t v = 0;
  for (int i = 0; i < 8; ++i) v |= static_cast<uint64_t>(in[i]) << (8 * i);
  return v;
}

// IEEE-754 binary32, by its bit pattern.
inline void StoreF32LE(uint8_t* out, float f) {
  uint32_t v;
  std::memcpy(&v, &f, sizeof(v));
  StoreU32LE(out, v);
}

inline float LoadF32LE(const uint8_t* in) {
  uint32_t v = LoadU32LE(in);
  float f;
  std::memcpy(&f, &v, sizeof(f));
  return f;
}

class ByteReader {
 public:
  explicit ByteReader(std::span<const uint8_t> data) : data_(data) {}

  size_t position() const { return pos_; }
  size_t remaining() const { return data_.size() - pos_; }

  bool ReadU8(uint8_t* v) {
    if (remaining() < 1) return false;
    *v = data_[pos_++];
    return true;
  }
  bool ReadU16(uint16_t* v) {
    if (remaining() < 2) return false;
    *v = LoadU16LE(data_.data() + pos_);
    pos_ += 2;
    return true;
  }
  bool ReadU32(uint32_t* v) {
    if (remaining() < 4) return false;
    *v = LoadU32LE(data_.data() + pos_);
    pos_ += 4;
    return true;
  }
  // Returns a view of the next `size` bytes (valid as long as the underlying data).
  bool ReadBytes(size_t size, std::span<const uint8_t>* out) {
    if (remaining() < size) return false;
    *out = data_.subspan(pos_, size);
    pos_ += size;
    return true;
  }

 private:
  std::span<const uint8_t> data_;
  size_t pos_ = 0;
};

class ByteWriter {
 public:
  explicit ByteWriter(std::span<uint8_t> out) : out_(out) {}

  size_t position() const { return pos_; }
  size_t remaining() const { return out_.size() - pos_; }

  bool WriteU8(uint8_t v) {
    if (remaining() < 1) return false;
    out_[pos_++] = v;
    return true;
  }
  bool WriteU16(uint16_t v) {
    if (remaining() < 2) return false;
    StoreU16LE(out_.data() + pos_, v);
    pos_ += 2;
    return true;
  }
  bool WriteU32(uint32_t v) {
    if (remaining() < 4) return false;
    StoreU32LE(out_.data() + pos_, v);
    pos_ += 4;
    return true;
  }
  bool WriteBytes(std::span<const uint8_t> bytes) {
    if (remaining() < bytes.size()) return false;
    if (!bytes.empty()) std::memcpy(out_.data() + pos_, bytes.data(), bytes.size());
    pos_ += bytes.size();
    return true;
  }

 private:
  std::span<uint8_t> out_;
  size_t pos_ = 0;
};

}  // namespace edgephys
