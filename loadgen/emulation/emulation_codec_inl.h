// Template part of emulation_codec.h. Include emulation_codec.h, not this file.
#pragma once

#include "protocol/byte_io.h"

namespace edgephys {

template <typename Lookup>
Status DecodeEmulationBatch(std::span<const uint8_t> payload, StateBatch* batch, Lookup&& previous) {
  const Status malformed = Status::Malformed("malformed emulation payload");
  batch->states.clear();
  if (payload.empty()) return malformed;
  if (payload[0] == kFormatPhoton) {
    constexpr size_t kHeader = 1 + 12, kMessage = 12 + 1 + 2 + 28;
    if (payload.size() < kHeader + kMessage || (payload.size() - kHeader) % kMessage != 0) {
      return malformed;
    }
    batch->time_ms = LoadU32LE(payload.data() + 1 + 4);
    size_t count = payload[1 + 3];
    if (count != (payload.size() - kHeader) / kMessage) return malformed;
    for (size_t i = 0; i < count; ++i) {
      const uint8_t* m = payload.data() + kHeader + i * kMessage;
      // The view id is 16 bits in Photon; the emulation keeps the entity id's high half in the
      // command header's sequence field's upper bytes so ids survive the round trip.
      EntityState s;
      s.entity_id = (LoadU32LE(m + 8) & 0xffff0000u) | LoadU16LE(m + 13);
      const uint8_t* f = m + 15;
      s.position = {LoadF32LE(f), LoadF32LE(f + 4), LoadF32LE(f + 8)};
      s.rotation = {LoadF32LE(f + 12), LoadF32LE(f + 16), LoadF32LE(f + 20), LoadF32LE(f + 24)};
      batch->states.push_back(s);
    }
    return Status::Ok();
  }
  if (payload[0] == kFormatPaper) {
    if (payload.size() < 7) return malformed;
    batch->time_ms = LoadU32LE(payload.data() + 1);
    size_t count = LoadU16LE(payload.data() + 5);
    size_t pos = 7;
    for (size_t i = 0; i < count; ++i) {
      if (pos + 5 > payload.size()) return malformed;
      EntityState s;
      s.entity_id = LoadU32LE(payload.data() + pos);
      uint8_t mask = payload[pos + 4];
      pos += 5;
      if ((mask & ~(kFieldPosition | kFieldRotation)) != 0 || mask == 0) return malformed;
      size_t need = ((mask & kFieldPosition) ? 12 : 0) + ((mask & kFieldRotation) ? 16 : 0);
      if (pos + need > payload.size()) return malformed;
      bool known = true;
      if (mask != (kFieldPosition | kFieldRotation)) known = previous(s.entity_id, &s);
      const uint8_t* f = payload.data() + pos;
      if (mask & kFieldPosition) {
        s.position = {LoadF32LE(f), LoadF32LE(f + 4), LoadF32LE(f + 8)};
        f += 12;
      }
      if (mask & kFieldRotation) {
        s.rotation = {LoadF32LE(f), LoadF32LE(f + 4), LoadF32LE(f + 8), LoadF32LE(f + 12)};
      }
      pos += need;
      if (known) batch->states.push_back(s);
    }
    if (pos != payload.size() || count == 0) return malformed;
    return Status::Ok();
  }
  return malformed;
}

}  // namespace edgephys
