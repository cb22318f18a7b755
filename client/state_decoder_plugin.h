// Client-side plug-in for state formats the SDK does not decode itself.
//
// The SDK decodes three state formats: 9 (shared delta, the relay's default), 2 (the previous
// default, kept for one release) and 11 (soft bodies). A payload of any other format is
// refused and counted (Client::state_payloads_refused()) unless the client was given a
// decoder here (ClientConfig::state_decoder). The benchmark emulations (loadgen/emulation/)
// are such decoders; only the load generator and tests link them.
//
// Thread-safety: Decode is const and called on the client's thread; one decoder may serve
// many clients.
#pragma once

#include <cstdint>
#include <functional>
#include <span>

#include "protocol/state_codec.h"
#include "protocol/status.h"

namespace edgephys {

class StateDecoderPlugin {
 public:
  virtual ~StateDecoderPlugin() = default;
  // The receiver's latest state of an entity (false if it has none).
  using Known = std::function<bool(uint32_t entity_id, EntityState* state)>;
  // Decodes `payload` (untrusted; payload[0] is its format) into `batch` (states replaced).
  // kMalformed, naming the cause, for a payload it cannot decode; values are validated by the
  // caller (IsValidState).
  virtual Status Decode(std::span<const uint8_t> payload, const Known& known,
                        StateBatch* batch) const = 0;
};

}  // namespace edgephys
