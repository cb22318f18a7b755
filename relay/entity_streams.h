// Which rigid-body state format a room sends, and each receiver's stream of it.
//
// The formats are rows of protocol/state_formats.cc (9, the default; 2 with
// ReplicationConfig::shared_encoding off, for one release); a ReplicationPlugin supplies
// others (relay/entity_stream.h).
//
// Thread-safety: pure functions; a stream belongs to one receiver (its room's thread).
#pragma once

#include <cstdint>
#include <memory>

#include "relay/entity_stream.h"

namespace edgephys {

struct ReplicationConfig;

// The stream a receiver in a room with `config` gets: the plug-in's if it has one, else the
// one of StateFormatOf(config). A quantisation MakeQuantizationParams refuses (the relay's flags
// and the admin API refuse them first) is replaced by the default one.
std::unique_ptr<StateStream> NewEntityStream(const ReplicationConfig& config);
// The format id rooms with `config` send and announce in Joined.
uint8_t StateFormatOf(const ReplicationConfig& config);

}  // namespace edgephys
