// Emulation formats: the same relay speaking like the baselines it is compared with, so that a
// benchmark measures all of them side by side in one run (docs/benchmarks.md,
// "Relay bandwidth"). Linked only by the load generator, bench/ and tests (through the
// plug-ins of loadgen/emulation/emulation_plugins.h), never by the relay binary or libedgephys.
//
// Format 3, "photon": one message per entity per send, full float transform, each message
// carrying the overhead of Photon's binary UDP protocol (a 12-byte command header per message,
// a 12-byte packet header per datagram) plus a PUN-style serialize payload (event code, 2-byte
// view id, 7 floats).
//   u8 format (3) | 12-byte packet header {u16 peer id, u8 flags, u8 command count,
//   u32 sent time (ms), u32 challenge} | count x { 12-byte command header {u8 type (7 =
//   send unreliable), u8 channel, u8 flags, u8 reserved, u32 length, u32 sequence} | u8 event
//   code | u16 view id | 7 x f32 }                                        = 43 bytes per entity
// Format 4, "paper": Decoupled Edge Physics' relay: grouped updates, a significance threshold
// (applied by the scheduler), a per-entity change bitmask and unquantised floats.
//   u8 format (4) | u32 time (ms) | u16 count | count x { u32 entity id | u8 mask (bit 0
//   position, bit 1 rotation) | [3 x f32 position] | [4 x f32 rotation] }   = 33 bytes per entity
//
// Thread-safety: encoder instances are not shared; decoding is a pure function.
#pragma once

#include <cstdint>
#include <span>

#include "protocol/state_codec.h"
#include "relay/entity_stream.h"  // kFieldPosition, kFieldRotation

namespace edgephys {

inline constexpr uint8_t kFormatPhoton = 3;  // ids reserved in protocol/state_codec.h
inline constexpr uint8_t kFormatPaper = 4;

// The emulations' shared bookkeeping: states appended after a fixed-size header that
// Finish() writes last.
class FixedHeaderEncoder : public ByteStateEncoder {
 public:
  // 0 if nothing was added; else the header written (WriteHeader) and the payload's size.
  size_t Finish() final {
    if (count_ == 0) return 0;
    WriteHeader(out_.data());
    return pos_;
  }

 protected:
  using ByteStateEncoder::ByteStateEncoder;
  // Counts one state of `bytes` just written at out_ + pos_; true.
  bool Appended(size_t bytes) {
    pos_ += bytes;
    ++count_;
    return true;
  }
  virtual void WriteHeader(uint8_t* header) const = 0;
};

class PhotonEmulationEncoder final : public FixedHeaderEncoder {
 public:
  PhotonEmulationEncoder();
  bool Add(const EntityState& state) override;

 private:
  void WriteHeader(uint8_t* header) const override;
  uint32_t sequence_ = 0;  // command sequence, continues across payloads
};

class PaperEmulationEncoder final : public FixedHeaderEncoder {
 public:
  PaperEmulationEncoder();
  bool Add(const EntityState& state) override { return AddFields(state, kFieldPosition | kFieldRotation); }
  // Adds only the fields in `mask` (the scheduler's significance test decides).
  bool AddFields(const EntityState& state, uint8_t mask);

 private:
  void WriteHeader(uint8_t* header) const override;
};

// Decodes format 3 or 4 into `batch` (states appended after clearing). For format 4 an entity
// whose mask omits a field gets that field from `previous` (a lookup of the receiver's last
// known state: returns false if unknown, in which case the entity is skipped).
// kMalformed on truncation, trailing bytes or a bad count.
template <typename Lookup>
Status DecodeEmulationBatch(std::span<const uint8_t> payload, StateBatch* batch, Lookup&& previous);

}  // namespace edgephys

#include "loadgen/emulation/emulation_codec_inl.h"
