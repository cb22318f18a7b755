#include "physics_backend/worker_protocol.h"

#include <cstring>

#include "protocol/byte_io.h"

namespace edgephys {
namespace {
constexpr size_t kBodySize = 13 * 4;
}  // namespace

size_t EncodeWorkerStates(uint32_t room, std::span<const RoomPhysics::MovedBody> bodies,
                          size_t first, std::span<uint8_t> out, size_t* encoded) {
  *encoded = 0;
  constexpr size_t kHeader = 1 + 4 + 5;
  if (out.size() < kHeader + 5 + kBodySize || first >= bodies.size()) return 0;
  size_t n = std::min(bodies.size() - first, (out.size() - kHeader) / (5 + kBodySize));
  size_t pos = 0;
  out[pos++] = kWorkerStateFormat;
  StoreU32LE(out.data() + pos, room);
  pos += 4;
  pos += PutVarint32(static_cast<uint32_t>(n), out.subspan(pos));
  for (size_t i = first; i < first + n; ++i) {
    const RoomPhysics::MovedBody& b = bodies[i];
    pos += PutVarint32(b.state.entity_id, out.subspan(pos));
    const float f[13] = {b.state.position.x, b.state.position.y, b.state.position.z,
                         b.state.rotation.x, b.state.rotation.y, b.state.rotation.z,
                         b.state.rotation.w, b.linear.x,         b.linear.y,
                         b.linear.z,         b.angular.x,        b.angular.y,
                         b.angular.z};
    for (float v : f) {
      StoreF32LE(out.data() + pos, v);
      pos += 4;
    }
  }
  *encoded = n;
  return pos;
}

Status DecodeWorkerStates(std::span<const uint8_t> payload, uint32_t* room,
                          std::vector<RoomPhysics::MovedBody>* out) {
  const Status malformed(StatusCode::kMalformed, "malformed worker states");
  if (payload.size() < 6 || payload[0] != kWorkerStateFormat) return malformed;
  *room = LoadU32LE(payload.data() + 1);
  uint32_t count = 0;
  size_t pos = 5;
  size_t n = GetVarint32(payload.subspan(pos), &count);
  if (n == 0) return malformed;
  pos += n;
  if (count > (payload.size() - pos) / (kBodySize + 1)) return malformed;
  for (uint32_t i = 0; i < count; ++i) {
    RoomPhysics::MovedBody b;
    n = GetVarint32(payload.subspan(pos), &b.state.entity_id);
    if (n == 0 || pos + n + kBodySize > payload.size()) return malformed;
    const uint8_t* p = payload.data() + pos + n;
    float f[13];
    for (int k = 0; k < 13; ++k) f[k] = LoadF32LE(p + 4 * k);
    b.state.position = {f[0], f[1], f[2]};
    b.state.rotation = {f[3], f[4], f[5], f[6]};
    b.linear = {f[7], f[8], f[9]};
    b.angular = {f[10], f[11], f[12]};
    out->push_back(b);
    pos += n + kBodySize;
  }
  if (pos != payload.size()) return malformed;
  return Status::Ok();
}

size_t EncodeWorkerSoftChunk(uint32_t room, uint32_t entity_id, std::span<const Vec3f> nodes,
                             uint32_t first, std::span<uint8_t> out, uint32_t* encoded) {
  *encoded = 0;
  if (out.size() < 8) return 0;
  out[0] = kWorkerSoftFormat;
  StoreU32LE(out.data() + 1, room);
  size_t n = EncodeSoftBodyChunk(0, entity_id, nodes, first, kWorkerSoftStepM, out.subspan(5),
                                 encoded);
  return n == 0 ? 0 : n + 5;
}

Status DecodeWorkerSoftChunk(std::span<const uint8_t> payload, uint32_t* room,
                             SoftBodyChunk* chunk) {
  if (payload.size() < 6 || payload[0] != kWorkerSoftFormat) {
    return Status(StatusCode::kMalformed, "malformed worker soft chunk");
  }
  *room = LoadU32LE(payload.data() + 1);
  return DecodeSoftBodyChunk(payload.subspan(5), kWorkerSoftStepM, 1 << 16, chunk);
}

EntityState FromPose(const schema::Pose& p) {
  return {p.entity_id(),
          {p.position().x(), p.position().y(), p.position().z()},
          {p.rotation().x(), p.rotation().y(), p.rotation().z(), p.rotation().w()}};
}

namespace {

// times[i], copied out: FlatBuffers' verifier checks a vector's length prefix to 4-byte
// alignment only, so in a hostile (verified) buffer the doubles may sit 4 bytes off 8-byte
// alignment, where reading them in place is undefined (UBSan's report from message_fuzz).
double TimeAt(const flatbuffers::Vector<double>& times, flatbuffers::uoffset_t i) {
  double t;
  std::memcpy(&t, times.Data() + static_cast<size_t>(i) * sizeof(double), sizeof t);
  return flatbuffers::EndianScalar(t);
}

}  // namespace

void ApplyWorkerDrive(const schema::WorkerDrive& message, RoomPhysics& room, double arrival) {
  const auto* poses = message.poses();
  if (poses == nullptr) return;
  const auto* times = message.times();
  const bool timed = times != nullptr && times->size() == poses->size();
  for (flatbuffers::uoffset_t i = 0; i < poses->size(); ++i) {
    const schema::Pose* p = poses->Get(i);
    room.Drive(p->entity_id(), FromPose(*p), timed ? TimeAt(*times, i) : arrival);
  }
}

}  // namespace edgephys
