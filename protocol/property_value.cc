#include "protocol/property_value.h"

#include <cmath>
#include <cstring>
#include <string>

#include "protocol/handshake.h"
#include "protocol/property_codec.h"

namespace edgephys {

size_t PropertyValue::size() const {
  switch (type) {
    case PropertyType::kBool: return 1;
    case PropertyType::kInt64:
    case PropertyType::kDouble: return 8;
    case PropertyType::kString:
    case PropertyType::kBytes: return text.size();
    case PropertyType::kVec3: return 12;
    case PropertyType::kQuat: return 16;
    case PropertyType::kNone: return 0;
  }
  return 0;
}

bool PropertyValue::operator==(const PropertyValue& o) const {
  if (type != o.type) return false;
  switch (type) {
    case PropertyType::kBool:
    case PropertyType::kInt64: return number == o.number;
    case PropertyType::kDouble: return real == o.real;
    case PropertyType::kString:
    case PropertyType::kBytes: return text == o.text;
    case PropertyType::kVec3: return vec.x == o.vec.x && vec.y == o.vec.y && vec.z == o.vec.z;
    case PropertyType::kQuat:
      return quat.x == o.quat.x && quat.y == o.quat.y && quat.z == o.quat.z && quat.w == o.quat.w;
    case PropertyType::kNone: return true;
  }
  return false;
}

Status ValidatePropertyKey(std::string_view key) {
  if (key.empty()) return Status::InvalidArgument("property key is empty");
  if (key.size() > kMaxPropertyKeyBytes) {
    return Status::InvalidArgument("property key longer than 64 bytes");
  }
  if (key.find('\0') != std::string_view::npos) {
    return Status::InvalidArgument("property key holds a NUL byte");
  }
  return Status::Ok();
}

Status ValidatePropertyValue(const PropertyValue& v) {
  const auto finite = [](std::initializer_list<double> xs) {
    for (double x : xs) {
      if (!std::isfinite(x)) return false;
    }
    return true;
  };
  switch (v.type) {
    case PropertyType::kBool:
      if (v.number != 0 && v.number != 1) return Status::InvalidArgument("bool value not 0 or 1");
      return Status::Ok();
    case PropertyType::kInt64: return Status::Ok();
    case PropertyType::kDouble:
      if (!finite({v.real})) return Status::InvalidArgument("double value is NaN or infinite");
      return Status::Ok();
    case PropertyType::kString:
    case PropertyType::kBytes:
      if (v.text.size() > kMaxPropertyValueBytes) {
        return Status::InvalidArgument("string/bytes value over 65536 bytes");
      }
      return Status::Ok();
    case PropertyType::kVec3:
      if (!finite({v.vec.x, v.vec.y, v.vec.z})) {
        return Status::InvalidArgument("vec3 value has a NaN or infinite component");
      }
      return Status::Ok();
    case PropertyType::kQuat:
      if (!finite({v.quat.x, v.quat.y, v.quat.z, v.quat.w})) {
        return Status::InvalidArgument("quat value has a NaN or infinite component");
      }
      return Status::Ok();
    case PropertyType::kNone: break;
  }
  return Status::InvalidArgument(
      "unknown property type",
      "unknown property type " + std::to_string(static_cast<unsigned>(v.type)));
}

std::string_view PropertyTypeName(PropertyType type) {
  switch (type) {
    case PropertyType::kBool: return "bool";
    case PropertyType::kInt64: return "int64";
    case PropertyType::kDouble: return "double";
    case PropertyType::kString: return "string";
    case PropertyType::kBytes: return "bytes";
    case PropertyType::kVec3: return "vec3";
    case PropertyType::kQuat: return "quat";
    case PropertyType::kNone: break;
  }
  return "none";
}

// --- wire -------------------------------------------------------------------------------------

flatbuffers::Offset<schema::PropertyValue> WritePropertyValue(flatbuffers::FlatBufferBuilder& fbb,
                                                              const PropertyValue& v) {
  flatbuffers::Offset<flatbuffers::String> text;
  flatbuffers::Offset<flatbuffers::Vector<uint8_t>> data;
  if (v.type == PropertyType::kString) text = fbb.CreateString(v.text);
  if (v.type == PropertyType::kBytes) {
    data = fbb.CreateVector(reinterpret_cast<const uint8_t*>(v.text.data()), v.text.size());
  }
  schema::PropertyValueBuilder b(fbb);
  b.add_type(static_cast<schema::PropertyType>(v.type));
  if (v.type == PropertyType::kBool || v.type == PropertyType::kInt64) b.add_number(v.number);
  if (v.type == PropertyType::kDouble) b.add_real(v.real);
  schema::Vec3 vec(v.vec.x, v.vec.y, v.vec.z);
  schema::Quat quat(v.quat.x, v.quat.y, v.quat.z, v.quat.w);
  if (v.type == PropertyType::kVec3) b.add_vec(&vec);
  if (v.type == PropertyType::kQuat) b.add_quat(&quat);
  if (v.type == PropertyType::kString) b.add_text(text);
  if (v.type == PropertyType::kBytes) b.add_data(data);
  return b.Finish();
}

PropertyValue ReadPropertyValue(const schema::PropertyValue* in) {
  PropertyValue v;
  if (in == nullptr) return v;
  v.type = static_cast<PropertyType>(in->type());
  v.number = in->number();
  v.real = in->real();
  const float nan = std::nanf("");
  if (const schema::Vec3* p = in->vec()) {
    v.vec = {p->x(), p->y(), p->z()};
  } else if (v.type == PropertyType::kVec3) {
    v.vec = {nan, nan, nan};
  }
  if (const schema::Quat* q = in->quat()) {
    v.quat = {q->x(), q->y(), q->z(), q->w()};
  } else if (v.type == PropertyType::kQuat) {
    v.quat = {nan, nan, nan, nan};
  }
  if (v.type == PropertyType::kString && in->text() != nullptr) v.text = in->text()->str();
  if (v.type == PropertyType::kBytes && in->data() != nullptr) {
    v.text.assign(reinterpret_cast<const char*>(in->data()->data()), in->data()->size());
  }
  return v;
}

void BuildPropertyChanged(flatbuffers::FlatBufferBuilder& fbb, const PropertyRecord& r) {
  fbb.Clear();
  const auto key = fbb.CreateString(r.key);
  const auto value = WritePropertyValue(fbb, r.value);
  FinishControl(fbb, schema::CreatePropertyChanged(
                         fbb, r.entity_id, key, value, r.version, r.writer, r.owner,
                         static_cast<schema::PropertyAuthority>(r.authority), r.request_id));
}

}  // namespace edgephys
