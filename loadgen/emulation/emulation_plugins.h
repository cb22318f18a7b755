// The benchmark emulations as plug-ins: the relay speaking like the baselines it is compared
// with (loadgen/emulation/emulation_codec.h), so that relay-compare and tests measure them
// side by side with the product's format in one run. Linked by the load generator, bench/ and
// tests only: the relay binary and libedgephys carry none of this.
//
//   mode      format  selection                                         relay side
//   edgephys  9       the product (no plug-in)                          built in
//   float     1       every unacknowledged version, resent when lost    FloatStateEncoder
//   photon    3       every entity at the fixed rate, changed or not    PhotonEmulationEncoder
//   paper     4       fields beyond the thresholds of the last SENT     PaperEmulationEncoder
//
// Thread-safety: the plug-ins are immutable and may be shared by any number of relays and
// clients; their streams are per receiver (relay/entity_stream.h).
#pragma once

#include <memory>
#include <string_view>

#include "client/state_decoder_plugin.h"
#include "relay/replication.h"

namespace edgephys {

enum class ReplicationMode : uint8_t { kEdgephys = 0, kFloat, kPhoton, kPaper };
std::string_view ReplicationModeName(ReplicationMode mode);
// Parses "edgephys", "float", "photon" or "paper"; false if unknown.
bool ParseReplicationMode(std::string_view text, ReplicationMode* mode);

// The relay plug-in of `mode` (null for kEdgephys: the relay's own format).
std::shared_ptr<const ReplicationPlugin> ReplicationPluginFor(ReplicationMode mode);
// Sets `config` to send `mode` (its plug-in, or none).
void UseReplicationMode(ReplicationMode mode, ReplicationConfig* config);

// Decodes formats 1, 3 and 4 for a client (ClientConfig::state_decoder). Format 4 entities
// that omit a field take it from the receiver's latest state; one it does not know is skipped.
std::shared_ptr<const StateDecoderPlugin> EmulationStateDecoder();

}  // namespace edgephys
