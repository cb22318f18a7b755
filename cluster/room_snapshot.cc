#include "cluster/room_snapshot.h"

#include <cmath>
#include <cstring>

#include "protocol/byte_io.h"

namespace edgephys::cluster {
namespace {

constexpr uint8_t kVersion = 1;
constexpr char kMagic[4] = {'E', 'P', 'R', 'S'};

class Writer {
 public:
  explicit Writer(std::vector<uint8_t>* out) : out_(out) {}
  void U8(uint8_t v) { out_->push_back(v); }
  void U32(uint32_t v) {
    size_t n = Grow(4);
    StoreU32LE(out_->data() + n, v);
  }
  void U64(uint64_t v) {
    size_t n = Grow(8);
    StoreU64LE(out_->data() + n, v);
  }
  void F32(float v) {
    size_t n = Grow(4);
    StoreF32LE(out_->data() + n, v);
  }
  void Vec(const Vec3f& v) { F32(v.x), F32(v.y), F32(v.z); }
  void Bytes(const void* p, size_t n) {
    size_t at = Grow(n);
    if (n > 0) std::memcpy(out_->data() + at, p, n);
  }

 private:
  size_t Grow(size_t n) {
    size_t at = out_->size();
    out_->resize(at + n);
    return at;
  }
  std::vector<uint8_t>* out_;
};

class Reader {
 public:
  explicit Reader(std::span<const uint8_t> in) : in_(in) {}
  bool ok() const { return ok_; }
  bool Need(size_t n) {
    if (!ok_ || in_.size() - pos_ < n) ok_ = false;
    return ok_;
  }
  uint8_t U8() { return Need(1) ? in_[pos_++] : 0; }
  uint32_t U32() {
    if (!Need(4)) return 0;
    uint32_t v = LoadU32LE(in_.data() + pos_);
    pos_ += 4;
    return v;
  }
  uint64_t U64() {
    if (!Need(8)) return 0;
    uint64_t v = LoadU64LE(in_.data() + pos_);
    pos_ += 8;
    return v;
  }
  float F32() {
    if (!Need(4)) return 0;
    float v = LoadF32LE(in_.data() + pos_);
    pos_ += 4;
    if (!std::isfinite(v)) ok_ = false;
    return v;
  }
  Vec3f Vec() {
    Vec3f v;
    v.x = F32();
    v.y = F32();
    v.z = F32();
    return v;
  }
  std::span<const uint8_t> Bytes(size_t n) {
    if (!Need(n)) return {};
    auto s = in_.subspan(pos_, n);
    pos_ += n;
    return s;
  }
  size_t left() const { return in_.size() - pos_; }

 private:
  std::span<const uint8_t> in_;
  size_t pos_ = 0;
  bool ok_ = true;
};

}  // namespace

std::vector<uint8_t> EncodeRoomSnapshot(const RoomSnapshot& s) {
  std::vector<uint8_t> out;
  size_t estimate = 64 + s.slots.size() * 8;
  for (const auto& e : s.entities) estimate += 96 + e.nodes.size() * 12 + e.spawn.size();
  out.reserve(estimate);
  Writer w(&out);
  w.Bytes(kMagic, 4);
  w.U8(kVersion);
  w.U8(static_cast<uint8_t>(s.room.size()));
  w.Bytes(s.room.data(), s.room.size());
  w.U64(s.written_unix_ms);
  w.U32(static_cast<uint32_t>(s.slots.size()));
  for (const auto& slot : s.slots) w.U32(slot.player_id), w.U32(slot.slot);
  w.U32(static_cast<uint32_t>(s.entities.size()));
  for (const EntitySnapshot& e : s.entities) {
    w.U32(e.id), w.U32(e.owner), w.U32(e.creator), w.U32(e.flags), w.U32(e.held_by);
    w.U8(e.physics_role);
    w.U64(e.spawn_seq);
    w.Vec(e.state.position);
    w.F32(e.state.rotation.x), w.F32(e.state.rotation.y), w.F32(e.state.rotation.z),
        w.F32(e.state.rotation.w);
    w.Vec(e.linear_velocity);
    w.Vec(e.angular_velocity);
    w.U32(static_cast<uint32_t>(e.nodes.size()));
    for (const Vec3f& n : e.nodes) w.Vec(n);
    w.U32(static_cast<uint32_t>(e.spawn.size()));
    w.Bytes(e.spawn.data(), e.spawn.size());
  }
  return out;
}

Result<RoomSnapshot> DecodeRoomSnapshot(std::span<const uint8_t> bytes) {
  const Status bad = Status::Malformed("bad room snapshot");
  Reader r(bytes);
  auto magic = r.Bytes(4);
  if (!r.ok() || std::memcmp(magic.data(), kMagic, 4) != 0) return bad;
  if (r.U8() != kVersion) return bad;
  RoomSnapshot s;
  uint8_t room_len = r.U8();
  auto room = r.Bytes(room_len);
  if (!r.ok() || room_len == 0 || room_len > 64) return bad;
  s.room.assign(reinterpret_cast<const char*>(room.data()), room.size());
  s.written_unix_ms = r.U64();
  uint32_t slots = r.U32();
  if (!r.ok() || slots > kMaxSnapshotSlots || slots > r.left() / 8) return bad;
  s.slots.resize(slots);
  for (auto& slot : s.slots) {
    slot.player_id = r.U32();
    slot.slot = r.U32();
    if (slot.player_id == 0 || slot.slot == 0 || slot.slot >= kEntityIdBlock) return bad;
  }
  uint32_t count = r.U32();
  constexpr size_t kMinEntityBytes = 5 * 4 + 1 + 8 + 13 * 4 + 4 + 4;
  if (!r.ok() || count > kMaxSnapshotEntities || count > r.left() / kMinEntityBytes) return bad;
  s.entities.resize(count);
  for (EntitySnapshot& e : s.entities) {
    e.id = r.U32(), e.owner = r.U32(), e.creator = r.U32(), e.flags = r.U32();
    e.held_by = r.U32();
    e.physics_role = r.U8();
    e.spawn_seq = r.U64();
    e.state.entity_id = e.id;
    e.state.position = r.Vec();
    e.state.rotation.x = r.F32(), e.state.rotation.y = r.F32(), e.state.rotation.z = r.F32();
    e.state.rotation.w = r.F32();
    e.linear_velocity = r.Vec();
    e.angular_velocity = r.Vec();
    uint32_t nodes = r.U32();
    if (!r.ok() || e.id == 0 || e.physics_role > 2 || nodes > kMaxSnapshotNodes ||
        nodes > r.left() / 12) {
      return bad;
    }
    e.nodes.resize(nodes);
    for (Vec3f& n : e.nodes) n = r.Vec();
    uint32_t spawn_len = r.U32();
    if (!r.ok() || spawn_len > kMaxSnapshotSpawnBytes) return bad;
    auto spawn = r.Bytes(spawn_len);
    if (!r.ok()) return bad;
    e.spawn.assign(spawn.begin(), spawn.end());
  }
  if (!r.ok() || r.left() != 0) return bad;
  return s;
}

}  // namespace edgephys::cluster
