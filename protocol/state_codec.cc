#include "protocol/state_codec.h"

#include <cmath>

#include "protocol/byte_io.h"

namespace edgephys {
namespace {

constexpr size_t kHeaderSize = 1 + 4 + 5;  // format, time, count (varint, reserved at max)
constexpr size_t kFloatEntitySize = 7 * 4;

bool Finite(float v) { return std::isfinite(v); }

}  // namespace

bool IsValidState(const EntityState& s) {
  const float c[7] = {s.position.x, s.position.y, s.position.z, s.rotation.x,
                      s.rotation.y, s.rotation.z, s.rotation.w};
  for (float v : c) {
    if (!Finite(v)) return false;
  }
  constexpr float kMaxCoord = 1e6f;
  if (std::fabs(s.position.x) > kMaxCoord || std::fabs(s.position.y) > kMaxCoord ||
      std::fabs(s.position.z) > kMaxCoord) {
    return false;
  }
  float n = s.rotation.x * s.rotation.x + s.rotation.y * s.rotation.y +
            s.rotation.z * s.rotation.z + s.rotation.w * s.rotation.w;
  return std::fabs(n - 1.0f) < 2e-3f;
}

size_t PutVarint32(uint32_t value, std::span<uint8_t> out) {
  size_t i = 0;
  do {
    if (i >= out.size()) return 0;
    uint8_t b = value & 0x7f;
    value >>= 7;
    out[i++] = static_cast<uint8_t>(b | (value != 0 ? 0x80 : 0));
  } while (value != 0);
  return i;
}

size_t GetVarint32(std::span<const uint8_t> in, uint32_t* value) {
  uint32_t v = 0;
  for (size_t i = 0; i < 5 && i < in.size(); ++i) {
    if (i == 4 && (in[i] & 0xf0) != 0) return 0;  // would overflow 32 bits
    v |= static_cast<uint32_t>(in[i] & 0x7f) << (7 * i);
    if ((in[i] & 0x80) == 0) {
      *value = v;
      return i + 1;
    }
  }
  return 0;
}

FloatStateEncoder::FloatStateEncoder() : ByteStateEncoder(kHeaderSize) {}

bool FloatStateEncoder::Add(const EntityState& s) {
  uint8_t id[5];
  size_t id_size = PutVarint32(s.entity_id, id);
  if (out_.size() < kHeaderSize || pos_ + id_size + kFloatEntitySize > out_.size()) return false;
  uint8_t* p = out_.data() + pos_;
  for (size_t i = 0; i < id_size; ++i) *p++ = id[i];
  const float c[7] = {s.position.x, s.position.y, s.position.z, s.rotation.x,
                      s.rotation.y, s.rotation.z, s.rotation.w};
  for (float v : c) {
    StoreF32LE(p, v);
    p += 4;
  }
  pos_ += id_size + kFloatEntitySize;
  ++count_;
  return true;
}

size_t FloatStateEncoder::Finish() {
  if (count_ == 0) return 0;
  // The header reserved 5 bytes for the count; write it compactly and close the gap.
  uint8_t* p = out_.data();
  p[0] = static_cast<uint8_t>(StateFormat::kFloat);
  StoreU32LE(p + 1, time_ms_);
  uint8_t cnt[5];
  size_t cnt_size = PutVarint32(static_cast<uint32_t>(count_), cnt);
  size_t body = pos_ - kHeaderSize;
  size_t dst = 5 + cnt_size;
  for (size_t i = 0; i < cnt_size; ++i) p[5 + i] = cnt[i];
  for (size_t i = 0; i < body; ++i) p[dst + i] = p[kHeaderSize + i];
  return dst + body;
}

Status DecodeStateBatch(std::span<const uint8_t> payload, StateBatch* batch) {
  const Status malformed = Status::Malformed("malformed state payload");
  batch->states.clear();
  if (!payload.empty() && payload[0] == static_cast<uint8_t>(StateFormat::kQuantizedDelta)) {
    return Status::InvalidArgument("format 2 payload needs a DeltaDecoder");
  }
  if (payload.size() < 6 || payload[0] != static_cast<uint8_t>(StateFormat::kFloat)) {
    return malformed;
  }
  batch->time_ms = LoadU32LE(payload.data() + 1);
  uint32_t count = 0;
  size_t n = GetVarint32(payload.subspan(5), &count);
  if (n == 0) return malformed;
  size_t pos = 5 + n;
  if (count == 0 || count > (payload.size() - pos) / (kFloatEntitySize + 1)) return malformed;
  for (uint32_t i = 0; i < count; ++i) {
    EntityState s;
    n = GetVarint32(payload.subspan(pos), &s.entity_id);
    if (n == 0 || pos + n + kFloatEntitySize > payload.size()) return malformed;
    const uint8_t* p = payload.data() + pos + n;
    s.position = {LoadF32LE(p), LoadF32LE(p + 4), LoadF32LE(p + 8)};
    s.rotation = {LoadF32LE(p + 12), LoadF32LE(p + 16), LoadF32LE(p + 20),
                  LoadF32LE(p + 24)};
    batch->states.push_back(s);
    pos += n + kFloatEntitySize;
  }
  if (pos != payload.size()) return malformed;
  return Status::Ok();
}

}  // namespace edgephys
