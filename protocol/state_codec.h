// State codec: the hot-path format for entity transforms on the unreliable channel
// (docs/protocol.md, "State payloads"). Both directions use it: owners publish to the relay,
// the relay fans out to the room.
//
// Every format starts with a one-byte format id so that encoders can be swapped per room
// without breaking receivers that know the format. This file defines format 1, "float":
//   u8 format (1) | u32 sender time (ms, wraps) | varint count |
//   count x { varint entity id | 3 x f32 position (m) | 4 x f32 rotation (x, y, z, w) }
// Precision: exact float32 (the encoder's stated precision is float32 rounding).
//
// Thread-safety: StateEncoder instances are not shared; the functions are pure.
// Cost: O(entities), no allocation (callers supply buffers).
#pragma once

#include <cstddef>
#include <cstdint>
#include <span>
#include <vector>

#include "protocol/status.h"
#include "protocol/types.h"

namespace edgephys {

// True if every component is finite, positions are within +-1e6 m and the rotation has unit
// length within 1e-3. Relays drop (and count) states that fail this.
bool IsValidState(const EntityState& state);

// The first byte of every state payload on the unreliable channel. Ids in use: 1 (kFloat, the
// clients' up-format), 2 (kQuantizedDelta, protocol/delta_codec.h), 5 (kSoftBody, soft-body
// particle chunks inside the PhyS worker link, protocol/soft_body_codec.h), 6 and 8 (the worker
// link's own, physics_backend/worker_protocol.h), 9 (protocol/shared_delta_codec.h), 11
// (protocol/soft_delta_codec.h), 15 (application messages, protocol/app_message_codec.h).
// 3 and 4 are reserved for the benchmark emulations (loadgen/emulation/), which the product
// neither sends nor decodes. kQuantizedDelta is stateful: it is decoded only by a DeltaDecoder
// owned by the stream's receiver, never by DecodeStateBatch.
enum class StateFormat : uint8_t {
  kFloat = 1,
  kQuantizedDelta = 2,
  kSoftBody = 5,
};

// Writes entity states into datagram payloads. Usage per payload:
//   encoder.Begin(buffer, time_ms); while (encoder.Add(state)) {...}; size = encoder.Finish();
class StateEncoder {
 public:
  virtual ~StateEncoder() = default;
  // Starts a payload in `out` (not owned; must stay valid until Finish()).
  virtual void Begin(std::span<uint8_t> out, uint32_t time_ms) = 0;
  // Appends `state`; false (and nothing written) when it does not fit.
  virtual bool Add(const EntityState& state) = 0;
  // Number of states added since Begin().
  virtual size_t count() const = 0;
  // Completes the payload; returns its size in bytes (0 if nothing was added).
  virtual size_t Finish() = 0;
};

// What the byte-aligned encoders (format 1 and the emulations) share: Begin() reserves a fixed-size
// header that Finish() fills in, and Add() appends after it.
class ByteStateEncoder : public StateEncoder {
 public:
  void Begin(std::span<uint8_t> out, uint32_t time_ms) final {
    out_ = out;
    pos_ = header_size_;
    count_ = 0;
    time_ms_ = time_ms;
  }
  size_t count() const final { return count_; }

 protected:
  explicit ByteStateEncoder(size_t header_size) : header_size_(header_size) {}

  size_t header_size_;      // bytes reserved at the start of the payload
  std::span<uint8_t> out_;  // the payload being written (not owned)
  size_t pos_ = 0;          // bytes of out_ used, header included
  size_t count_ = 0;        // states added since Begin()
  uint32_t time_ms_ = 0;    // the payload's sender time
};

// Format 1 encoder.
class FloatStateEncoder final : public ByteStateEncoder {
 public:
  FloatStateEncoder();
  bool Add(const EntityState& state) override;
  size_t Finish() override;
};

struct StateBatch {
  uint32_t time_ms = 0;
  std::vector<EntityState> states;  // reused by the caller between decodes
};

// The receiving end of a stateful format (one per receiver and stream): what the SDK holds
// for the room's format (protocol/state_formats.h picks it by id).
class StateDecoder {
 public:
  virtual ~StateDecoder() = default;
  // Decodes one payload (untrusted; payload[0] is its format). On success sets out->time_ms
  // and APPENDS the states it yields; kMalformed naming the cause otherwise, with `out` and the
  // decoder unchanged. Values are validated by the caller (IsValidState).
  virtual Status Decode(std::span<const uint8_t> payload, StateBatch* out) = 0;
  // Drops what is held for `entity_id` (despawned).
  virtual void Forget(uint32_t entity_id) = 0;
};

// Decodes format 1 (a client's states on their way up to the relay). Untrusted input: kMalformed on truncation,
// trailing bytes, an unknown format or a count larger than the payload can hold; `batch` is
// then unspecified. A format-2 payload returns kInvalidArgument ("needs a DeltaDecoder"):
// dispatch on payload[0] == StateFormat::kQuantizedDelta to the stream's DeltaDecoder.
// Values are not validated here (see IsValidState).
Status DecodeStateBatch(std::span<const uint8_t> payload, StateBatch* batch);

// Varint (LEB128, 7 bits a byte) helpers. Put returns bytes written (0 if `out` is too short);
// Get returns bytes read (0 on truncation or a value longer than 5 bytes).
size_t PutVarint32(uint32_t value, std::span<uint8_t> out);
size_t GetVarint32(std::span<const uint8_t> in, uint32_t* value);

}  // namespace edgephys
