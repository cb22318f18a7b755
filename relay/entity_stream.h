// The relay's replication plug-ins: state formats the relay does not carry.
//
// The relay's own formats are rows of protocol/state_formats.cc, each a StateStream per receiver
// (protocol/state_stream.h) that the ClientReplicator (relay/replication.h) schedules. A
// ReplicationPlugin (ReplicationConfig::plugin) supplies streams of another format: the benchmark
// emulations of loadgen/emulation/, which only the load generator, bench/ and tests link. Soft
// bodies always go as format 11, beside the stream.
//
// Thread-safety: a ReplicationPlugin is immutable and shared by every room of a relay (any
// thread); its streams belong to one receiver each and are used on its room's thread only.
#pragma once

#include <cstdint>
#include <memory>
#include <string_view>

#include "protocol/state_stream.h"

namespace edgephys {

struct ReplicationConfig;

class ReplicationPlugin {
 public:
  virtual ~ReplicationPlugin() = default;
  virtual std::string_view name() const = 0;
  // The first byte of its payloads, announced to clients in Joined (the SDK refuses and counts
  // a format it does not decode unless the client was given a matching decoder,
  // client/state_decoder_plugin.h).
  virtual uint8_t state_format() const = 0;
  virtual std::unique_ptr<StateStream> NewStream(const ReplicationConfig& config) const = 0;
};

}  // namespace edgephys
