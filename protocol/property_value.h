// Properties (docs/protocol.md, "Properties"): a typed value under a short key, of the room or
// of one entity, shared by every member of the room. This header holds the plain value type
// both ends use and its checks; the wire form is protocol/property_codec.h.
//
// Thread-safety: plain data and pure functions. No allocation except the string/bytes copy.
#pragma once

#include <cstddef>
#include <cstdint>
#include <string>
#include <string_view>

#include "protocol/status.h"
#include "protocol/types.h"

namespace edgephys {

// Numbers are those of schema PropertyType (schema/control.fbs) and of the C API.
enum class PropertyType : uint8_t {
  kNone = 0,  // no value (a conflict on a property that does not exist)
  kBool = 1,
  kInt64 = 2,
  kDouble = 3,
  kString = 4,  // UTF-8 (not checked by the relay)
  kBytes = 5,
  kVec3 = 6,
  kQuat = 7,
};
inline constexpr uint8_t kMaxPropertyType = 7;

// Who may write a property (schema PropertyAuthority).
enum class PropertyAuthority : uint8_t {
  kOwner = 0,   // the entity's owner; for a room property, the player who created it
  kAnyone = 1,  // any member of the room
};

// Longest key, bytes (a key is 1..kMaxPropertyKeyBytes bytes, no NUL).
inline constexpr size_t kMaxPropertyKeyBytes = 64;
// Longest string/bytes value the protocol carries; a room's budget may allow less
// (RoomBudgets::max_property_value_bytes).
inline constexpr size_t kMaxPropertyValueBytes = 64 * 1024;

struct PropertyValue {
  PropertyType type = PropertyType::kNone;
  int64_t number = 0;  // kBool (0 or 1), kInt64
  double real = 0;     // kDouble
  Vec3f vec;           // kVec3
  Quatf quat;          // kQuat
  std::string text;    // kString, kBytes

  static PropertyValue Bool(bool v) { return {PropertyType::kBool, v ? 1 : 0}; }
  static PropertyValue Int64(int64_t v) { return {PropertyType::kInt64, v}; }
  static PropertyValue Double(double v) { return {PropertyType::kDouble, 0, v}; }
  static PropertyValue String(std::string_view v) {
    PropertyValue p;
    p.type = PropertyType::kString;
    p.text.assign(v);
    return p;
  }
  static PropertyValue Bytes(std::string_view v) {
    PropertyValue p = String(v);
    p.type = PropertyType::kBytes;
    return p;
  }
  static PropertyValue Vec3(const Vec3f& v) {
    PropertyValue p;
    p.type = PropertyType::kVec3;
    p.vec = v;
    return p;
  }
  static PropertyValue Quat(const Quatf& q) {
    PropertyValue p;
    p.type = PropertyType::kQuat;
    p.quat = q;
    return p;
  }

  // Bytes the value costs in a room's property budget: its payload (8 for numbers, 12 for a
  // vec3, 16 for a quat, the length for string/bytes, 1 for a bool).
  size_t size() const;
  // Same type and payload (fields of other types are ignored; doubles compare as numbers).
  bool operator==(const PropertyValue& o) const;
};

// One property as the relay announced it (PropertyChanged, or PropertyConflict's current
// state).
struct PropertyRecord {
  uint32_t entity_id = 0;  // 0: a room property
  std::string key;
  PropertyValue value;
  uint32_t version = 0;    // 0: the property does not exist (a conflict's current state)
  uint32_t writer = 0;     // player who wrote `value`
  uint32_t owner = 0;      // room properties: the creator; entity properties: 0
  PropertyAuthority authority = PropertyAuthority::kOwner;
  uint32_t request_id = 0; // the writer's request (PropertyChanged); the refused one (Conflict)
};

// OK, or kInvalidArgument naming the cause: an empty key, one over kMaxPropertyKeyBytes, or one
// holding a NUL byte.
Status ValidatePropertyKey(std::string_view key);
// OK, or kInvalidArgument naming the cause (Status::reason()): type kNone or unknown, a bool other than 0/1, a
// NaN or infinite double/vec3/quat component, string/bytes over kMaxPropertyValueBytes.
Status ValidatePropertyValue(const PropertyValue& value);
// "bool", "int64", ...; "none" for kNone and unknown numbers.
std::string_view PropertyTypeName(PropertyType type);

}  // namespace edgephys
