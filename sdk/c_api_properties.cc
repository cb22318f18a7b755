// The C API's properties (include/edgephys/edgephys_app_state.h, "properties") over Client::SetProperty,
// CompareAndSetProperty and FindProperty, and the property of the event polled last.
#include <cmath>
#include <cstring>
#include <new>
#include <string>
#include <string_view>

#include "client/client.h"
#include "edgephys/edgephys.h"
#include "sdk/c_api_client.h"

using edgephys::PropertyAuthority;
using edgephys::PropertyRecord;
using edgephys::PropertyType;
using edgephys::PropertyValue;
using edgephys::capi::CheckHandle;
using edgephys::capi::Guarded;
using edgephys::capi::SetError;
using edgephys::capi::SetStatus;

namespace {

// The C value as a PropertyValue; EDGEPHYS_OK or the error (recorded).
edgephys_status FromC(const edgephys_property_value* in, PropertyValue* out) {
  if (in == nullptr) return SetError(EDGEPHYS_E_INVALID_ARGUMENT, "value is NULL");
  if (in->type == EDGEPHYS_PROPERTY_NONE || in->type > EDGEPHYS_PROPERTY_QUAT) {
    return SetError(EDGEPHYS_E_INVALID_ARGUMENT, "unknown property type");
  }
  out->type = static_cast<PropertyType>(in->type);
  switch (in->type) {
    case EDGEPHYS_PROPERTY_BOOL:
    case EDGEPHYS_PROPERTY_INT64: out->number = in->int_value; break;
    case EDGEPHYS_PROPERTY_DOUBLE: out->real = in->double_value; break;
    case EDGEPHYS_PROPERTY_VEC3: out->vec = {in->vec3.x, in->vec3.y, in->vec3.z}; break;
    case EDGEPHYS_PROPERTY_QUAT: out->quat = {in->quat.x, in->quat.y, in->quat.z, in->quat.w}; break;
    default:  // STRING, BYTES
      if (in->size > EDGEPHYS_MAX_PROPERTY_VALUE_BYTES) {
        return SetError(EDGEPHYS_E_TOO_LARGE, "value over EDGEPHYS_MAX_PROPERTY_VALUE_BYTES");
      }
      if (in->data == nullptr && in->size > 0) {
        return SetError(EDGEPHYS_E_INVALID_ARGUMENT, "value data is NULL");
      }
      if (in->size > 0) out->text.assign(static_cast<const char*>(in->data), in->size);
      break;
  }
  return EDGEPHYS_OK;
}

// Copies `p` into *out and its string/bytes into `buffer`.
edgephys_status ToC(const PropertyRecord& p, edgephys_property* out, void* buffer,
                    size_t capacity) {
  const bool has_bytes = p.value.type == PropertyType::kString || p.value.type == PropertyType::kBytes;
  const size_t size = has_bytes ? p.value.text.size() : 0;
  if (size > capacity) {
    out->value.size = size;
    return SetError(EDGEPHYS_E_BUFFER_TOO_SMALL, "buffer smaller than the property's value");
  }
  if (size > 0 && buffer == nullptr) return SetError(EDGEPHYS_E_INVALID_ARGUMENT, "buffer is NULL");
  edgephys_property r;
  std::memset(&r, 0, sizeof(r));
  r.struct_size = sizeof(r);
  r.entity_id = p.entity_id;
  r.version = p.version;
  r.writer = p.writer;
  r.owner = p.owner;
  r.authority = static_cast<uint32_t>(p.authority);
  r.request_id = p.request_id;
  r.value.type = static_cast<uint32_t>(p.value.type);
  switch (p.value.type) {
    case PropertyType::kBool:
    case PropertyType::kInt64: r.value.int_value = p.value.number; break;
    case PropertyType::kDouble: r.value.double_value = p.value.real; break;
    case PropertyType::kVec3: r.value.vec3 = {p.value.vec.x, p.value.vec.y, p.value.vec.z}; break;
    case PropertyType::kQuat:
      r.value.quat = {p.value.quat.x, p.value.quat.y, p.value.quat.z, p.value.quat.w};
      break;
    default: break;
  }
  if (has_bytes) {
    if (size > 0) std::memcpy(buffer, p.value.text.data(), size);
    r.value.data = buffer;
    r.value.size = size;
  }
  *out = r;
  return SetStatus(edgephys::Status::Ok());
}

edgephys_status Write(edgephys_client* client, uint32_t entity_id, const char* key,
                      const edgephys_property_value* value, bool check, uint32_t expected,
                      uint32_t authority, uint32_t* out_request_id) {
  if (edgephys_status s = CheckHandle(client); s != EDGEPHYS_OK) return s;
  return Guarded([&]() -> edgephys_status {
    if (key == nullptr) return SetError(EDGEPHYS_E_INVALID_ARGUMENT, "key is NULL");
    if (authority > EDGEPHYS_AUTHORITY_ANYONE) {
      return SetError(EDGEPHYS_E_INVALID_ARGUMENT, "unknown property authority");
    }
    const std::string_view k(key, strnlen(key, EDGEPHYS_MAX_PROPERTY_KEY_BYTES + 1));
    PropertyValue v;
    if (edgephys_status s = FromC(value, &v); s != EDGEPHYS_OK) return s;
    const auto a = static_cast<PropertyAuthority>(authority);
    edgephys::Result<uint32_t> r = check
        ? client->client->CompareAndSetProperty(entity_id, k, v, expected, a)
        : client->client->SetProperty(entity_id, k, v, a);
    if (!r.ok()) return SetStatus(r.status());
    if (out_request_id != nullptr) *out_request_id = *r;
    return SetStatus(edgephys::Status::Ok());
  });
}

edgephys_status CheckOut(const edgephys_property* out) {
  if (out == nullptr) return SetError(EDGEPHYS_E_INVALID_ARGUMENT, "out is NULL");
  if (out->struct_size != sizeof(edgephys_property)) {
    return SetError(EDGEPHYS_E_INVALID_ARGUMENT,
                    "out->struct_size is not sizeof(edgephys_property)");
  }
  return EDGEPHYS_OK;
}

}  // namespace

extern "C" {

edgephys_status edgephys_client_set_property(edgephys_client* client, uint32_t entity_id,
                                             const char* key, const edgephys_property_value* value,
                                             uint32_t authority, uint32_t* out_request_id) {
  return Write(client, entity_id, key, value, false, 0, authority, out_request_id);
}

edgephys_status edgephys_client_compare_and_set_property(edgephys_client* client,
                                                         uint32_t entity_id, const char* key,
                                                         const edgephys_property_value* value,
                                                         uint32_t expected_version,
                                                         uint32_t authority,
                                                         uint32_t* out_request_id) {
  return Write(client, entity_id, key, value, true, expected_version, authority, out_request_id);
}

edgephys_status edgephys_client_get_property(edgephys_client* client, uint32_t entity_id,
                                             const char* key, edgephys_property* out, void* buffer,
                                             size_t capacity) {
  if (edgephys_status s = CheckHandle(client); s != EDGEPHYS_OK) return s;
  if (key == nullptr) return SetError(EDGEPHYS_E_INVALID_ARGUMENT, "key is NULL");
  if (edgephys_status s = CheckOut(out); s != EDGEPHYS_OK) return s;
  return Guarded([&]() -> edgephys_status {
    const std::string_view k(key, strnlen(key, EDGEPHYS_MAX_PROPERTY_KEY_BYTES + 1));
    const PropertyRecord* p = client->client->FindProperty(entity_id, k);
    if (p == nullptr) return SetError(EDGEPHYS_E_NOT_FOUND, "no such property known");
    return ToC(*p, out, buffer, capacity);
  });
}

edgephys_status edgephys_client_get_event_property(edgephys_client* client, edgephys_property* out,
                                                   void* buffer, size_t capacity) {
  if (edgephys_status s = CheckHandle(client); s != EDGEPHYS_OK) return s;
  if (edgephys_status s = CheckOut(out); s != EDGEPHYS_OK) return s;
  if (!client->has_polled_property) {
    return SetError(EDGEPHYS_E_NOT_FOUND, "the event polled last is not a property event");
  }
  return ToC(client->polled_property, out, buffer, capacity);
}

}  // extern "C"
