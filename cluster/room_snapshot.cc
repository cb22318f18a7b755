#include "cluster/room_snapshot.h"

#include <cmath>
#include <cstring>

#include "protocol/byte_io.h"

namespace edgephys::cluster {
namespace {

constexpr uint8_t kVersion = 3;  // 1: no property section; 2: no ownership section
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
  void F64(double v) {
    uint64_t bits;
    std::memcpy(&bits, &v, 8);
    U64(bits);
  }
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
  double F64() {
    const uint64_t bits = U64();
    double v;
    std::memcpy(&v, &bits, 8);
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

void WriteProperty(Writer& w, const PropertySnapshot& p) {
  w.U32(p.entity_id);
  w.U8(static_cast<uint8_t>(p.key.size()));
  w.Bytes(p.key.data(), p.key.size());
  w.U8(static_cast<uint8_t>(p.value.type));
  w.U8(static_cast<uint8_t>(p.authority));
  w.U32(p.version), w.U32(p.writer), w.U32(p.owner), w.U32(p.request_id);
  switch (p.value.type) {
    case PropertyType::kBool:
    case PropertyType::kInt64: w.U64(static_cast<uint64_t>(p.value.number)); break;
    case PropertyType::kDouble: w.F64(p.value.real); break;
    case PropertyType::kVec3: w.Vec(p.value.vec); break;
    case PropertyType::kQuat:
      w.F32(p.value.quat.x), w.F32(p.value.quat.y), w.F32(p.value.quat.z), w.F32(p.value.quat.w);
      break;
    case PropertyType::kString:
    case PropertyType::kBytes:
      w.U32(static_cast<uint32_t>(p.value.text.size()));
      w.Bytes(p.value.text.data(), p.value.text.size());
      break;
    case PropertyType::kNone: break;
  }
}

// False on any violation (the reader is then not ok() or the property is invalid).
bool ReadProperty(Reader& r, PropertySnapshot* p) {
  p->entity_id = r.U32();
  const uint8_t key_len = r.U8();
  const auto key = r.Bytes(key_len);
  if (!r.ok()) return false;
  p->key.assign(reinterpret_cast<const char*>(key.data()), key.size());
  p->value.type = static_cast<PropertyType>(r.U8());
  const uint8_t authority = r.U8();
  p->authority = static_cast<PropertyAuthority>(authority);
  p->version = r.U32(), p->writer = r.U32(), p->owner = r.U32(), p->request_id = r.U32();
  switch (p->value.type) {
    case PropertyType::kBool:
    case PropertyType::kInt64: p->value.number = static_cast<int64_t>(r.U64()); break;
    case PropertyType::kDouble: p->value.real = r.F64(); break;
    case PropertyType::kVec3: p->value.vec = r.Vec(); break;
    case PropertyType::kQuat:
      p->value.quat.x = r.F32(), p->value.quat.y = r.F32(), p->value.quat.z = r.F32();
      p->value.quat.w = r.F32();
      break;
    case PropertyType::kString:
    case PropertyType::kBytes: {
      const uint32_t n = r.U32();
      if (!r.ok() || n > kMaxPropertyValueBytes) return false;
      const auto bytes = r.Bytes(n);
      p->value.text.assign(reinterpret_cast<const char*>(bytes.data()), bytes.size());
      break;
    }
    case PropertyType::kNone: return false;
    default: return false;
  }
  return r.ok() && authority <= static_cast<uint8_t>(PropertyAuthority::kAnyone) &&
         p->version != 0 && ValidatePropertyKey(p->key).ok() &&
         ValidatePropertyValue(p->value).ok();
}

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
  w.U32(static_cast<uint32_t>(s.properties.size()));
  for (const PropertySnapshot& p : s.properties) WriteProperty(w, p);
  w.U32(static_cast<uint32_t>(s.entities.size()));
  for (const EntitySnapshot& e : s.entities) {
    w.U32(e.id), w.U32(e.authority_seq), w.U32(e.former_owner);
    w.U8(e.takeover_allowed ? 1 : 0), w.U8(e.on_owner_leave);
  }
  return out;
}

Result<RoomSnapshot> DecodeRoomSnapshot(std::span<const uint8_t> bytes) {
  const Status bad = Status::Malformed("bad room snapshot");
  Reader r(bytes);
  auto magic = r.Bytes(4);
  if (!r.ok() || std::memcmp(magic.data(), kMagic, 4) != 0) return bad;
  const uint8_t version = r.U8();
  if (version < 1 || version > kVersion) return bad;
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
  if (version >= 2) {
    const uint32_t properties = r.U32();
    constexpr size_t kMinPropertyBytes = 4 + 1 + 1 + 1 + 1 + 16 + 4;
    if (!r.ok() || properties > kMaxSnapshotProperties || properties > r.left() / kMinPropertyBytes) {
      return bad;
    }
    s.properties.resize(properties);
    for (PropertySnapshot& p : s.properties) {
      if (!ReadProperty(r, &p)) return bad;
    }
  }
  if (version >= 3) {
    // One ownership record per entity, in the entities' order.
    if (r.U32() != s.entities.size() || !r.ok()) return bad;
    for (EntitySnapshot& e : s.entities) {
      const uint32_t id = r.U32();
      e.authority_seq = r.U32(), e.former_owner = r.U32();
      const uint8_t takeover = r.U8();
      e.on_owner_leave = r.U8();
      if (!r.ok() || id != e.id || takeover > 1 || e.on_owner_leave > kMaxOwnerLeave) return bad;
      e.takeover_allowed = takeover != 0;
    }
  }
  if (!r.ok() || r.left() != 0) return bad;
  return s;
}

}  // namespace edgephys::cluster
