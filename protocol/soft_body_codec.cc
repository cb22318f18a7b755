#include "protocol/soft_body_codec.h"

#include <algorithm>
#include <cmath>

#include "protocol/byte_io.h"

namespace edgephys {
namespace {
constexpr size_t kMaxHeader = 1 + 4 + 5 * 4 + 12;
}  // namespace

size_t EncodeSoftBodyChunk(uint32_t time_ms, uint32_t entity_id, std::span<const Vec3f> nodes,
                           uint32_t first, float step_m, std::span<uint8_t> out,
                           uint32_t* encoded) {
  *encoded = 0;
  if (first >= nodes.size() || out.size() < kMaxHeader + 6 || step_m <= 0) return 0;
  uint32_t n = static_cast<uint32_t>(
      std::min<size_t>(nodes.size() - first, (out.size() - kMaxHeader) / 6));
  Vec3f lo = nodes[first];
  for (uint32_t i = first; i < first + n; ++i) {
    lo.x = std::min(lo.x, nodes[i].x);
    lo.y = std::min(lo.y, nodes[i].y);
    lo.z = std::min(lo.z, nodes[i].z);
  }
  size_t pos = 0;
  out[pos++] = kSoftBodyFormat;
  StoreU32LE(out.data() + pos, time_ms);
  pos += 4;
  for (uint32_t v : {entity_id, static_cast<uint32_t>(nodes.size()), first, n}) {
    pos += PutVarint32(v, out.subspan(pos));
  }
  StoreF32LE(out.data() + pos, lo.x);
  StoreF32LE(out.data() + pos + 4, lo.y);
  StoreF32LE(out.data() + pos + 8, lo.z);
  pos += 12;
  auto q = [step_m](float v, float origin) {
    double steps = std::round((static_cast<double>(v) - origin) / step_m);
    return static_cast<uint16_t>(std::clamp(steps, 0.0, 65535.0));
  };
  for (uint32_t i = first; i < first + n; ++i) {
    StoreU16LE(out.data() + pos, q(nodes[i].x, lo.x));
    StoreU16LE(out.data() + pos + 2, q(nodes[i].y, lo.y));
    StoreU16LE(out.data() + pos + 4, q(nodes[i].z, lo.z));
    pos += 6;
  }
  *encoded = n;
  return pos;
}

Status DecodeSoftBodyChunk(std::span<const uint8_t> payload, float step_m, uint32_t max_total,
                           SoftBodyChunk* out) {
  const Status malformed = Status::Malformed("malformed soft body payload");
  if (payload.size() < 5 || payload[0] != kSoftBodyFormat) return malformed;
  out->time_ms = LoadU32LE(payload.data() + 1);
  size_t pos = 5;
  uint32_t v[4];
  for (uint32_t& x : v) {
    size_t n = GetVarint32(payload.subspan(pos), &x);
    if (n == 0) return malformed;
    pos += n;
  }
  out->entity_id = v[0];
  out->total = v[1];
  out->first = v[2];
  uint32_t count = v[3];
  if (out->total == 0 || out->total > max_total || count == 0 || out->first >= out->total ||
      count > out->total - out->first || payload.size() != pos + 12 + size_t{count} * 6) {
    return malformed;
  }
  Vec3f origin{LoadF32LE(payload.data() + pos), LoadF32LE(payload.data() + pos + 4),
               LoadF32LE(payload.data() + pos + 8)};
  if (!std::isfinite(origin.x) || !std::isfinite(origin.y) || !std::isfinite(origin.z)) {
    return malformed;
  }
  pos += 12;
  out->positions.resize(count);
  for (uint32_t i = 0; i < count; ++i, pos += 6) {
    out->positions[i] = {origin.x + LoadU16LE(payload.data() + pos) * step_m,
                         origin.y + LoadU16LE(payload.data() + pos + 2) * step_m,
                         origin.z + LoadU16LE(payload.data() + pos + 4) * step_m};
  }
  return Status::Ok();
}

}  // namespace edgephys
