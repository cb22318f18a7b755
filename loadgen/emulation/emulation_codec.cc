#include "loadgen/emulation/emulation_codec.h"

#include "protocol/byte_io.h"

namespace edgephys {
namespace {
constexpr size_t kPhotonHeader = 1 + 12;
constexpr size_t kPhotonMessage = 12 + 1 + 2 + 28;
constexpr size_t kPhotonMaxCommands = 255;
constexpr size_t kPaperHeader = 1 + 4 + 2;
}  // namespace

PhotonEmulationEncoder::PhotonEmulationEncoder() : FixedHeaderEncoder(kPhotonHeader) {}

bool PhotonEmulationEncoder::Add(const EntityState& s) {
  if (count_ >= kPhotonMaxCommands || pos_ + kPhotonMessage > out_.size()) return false;
  uint8_t* m = out_.data() + pos_;
  m[0] = 7;  // send unreliable
  m[1] = 0;  // channel
  m[2] = 0;  // flags
  m[3] = 0;
  StoreU32LE(m + 4, static_cast<uint32_t>(kPhotonMessage));
  // Sequence: low half counts commands; the high half carries the entity id's high half so
  // that ids above 65535 survive the 16-bit view id (Photon would use a view id lookup).
  StoreU32LE(m + 8, (s.entity_id & 0xffff0000u) | (sequence_++ & 0xffffu));
  m[12] = 201;  // PUN's serialize event code
  StoreU16LE(m + 13, static_cast<uint16_t>(s.entity_id & 0xffffu));
  const float f[7] = {s.position.x, s.position.y, s.position.z, s.rotation.x,
                      s.rotation.y, s.rotation.z, s.rotation.w};
  for (int i = 0; i < 7; ++i) StoreF32LE(m + 15 + 4 * i, f[i]);
  return Appended(kPhotonMessage);
}

void PhotonEmulationEncoder::WriteHeader(uint8_t* p) const {
  p[0] = kFormatPhoton;
  StoreU16LE(p + 1, 1);  // peer id
  p[3] = 0;              // flags
  p[4] = static_cast<uint8_t>(count_);
  StoreU32LE(p + 5, time_ms_);
  StoreU32LE(p + 9, 0x5048u);  // challenge
}

PaperEmulationEncoder::PaperEmulationEncoder() : FixedHeaderEncoder(kPaperHeader) {}

bool PaperEmulationEncoder::AddFields(const EntityState& s, uint8_t mask) {
  mask &= kFieldPosition | kFieldRotation;
  if (mask == 0) return true;  // nothing significant: nothing to send
  size_t need = 5 + ((mask & kFieldPosition) ? 12 : 0) + ((mask & kFieldRotation) ? 16 : 0);
  if (count_ >= 0xffff || pos_ + need > out_.size()) return false;
  uint8_t* p = out_.data() + pos_;
  StoreU32LE(p, s.entity_id);
  p[4] = mask;
  p += 5;
  if (mask & kFieldPosition) {
    StoreF32LE(p, s.position.x);
    StoreF32LE(p + 4, s.position.y);
    StoreF32LE(p + 8, s.position.z);
    p += 12;
  }
  if (mask & kFieldRotation) {
    StoreF32LE(p, s.rotation.x);
    StoreF32LE(p + 4, s.rotation.y);
    StoreF32LE(p + 8, s.rotation.z);
    StoreF32LE(p + 12, s.rotation.w);
  }
  return Appended(need);
}

void PaperEmulationEncoder::WriteHeader(uint8_t* p) const {
  p[0] = kFormatPaper;
  StoreU32LE(p + 1, time_ms_);
  StoreU16LE(p + 5, static_cast<uint16_t>(count_));
}

}  // namespace edgephys
