// The state formats the SDK decodes, by id: what a client builds for the format its room
// announces in Joined.
//
// One row each in state_formats.cc: 9 (shared delta, the relay's default) and 2 (the previous
// default, decodable for one release). Soft bodies (format 11, protocol/soft_delta_stream.h)
// decode into particles, not states, and are not rows. A format of a plug-in (the benchmark
// emulations) is decoded by the client's StateDecoderPlugin (client/state_decoder_plugin.h).
// The relay's side of each format is a row of relay/entity_streams.cc.
//
// Adding a format: its codec file (encoder and a StateDecoder) with its test, a row here and
// one in relay/entity_streams.cc.
//
// Thread-safety: pure functions. Each decoder belongs to one receiver.
#pragma once

#include <cstdint>
#include <memory>

#include "protocol/quantize.h"
#include "protocol/state_codec.h"

namespace edgephys {

// A new decoder of `format` for a room quantised by `params`; nullptr if the SDK does not
// decode `format`.
std::unique_ptr<StateDecoder> NewStateDecoder(uint8_t format, const QuantizationParams& params);

}  // namespace edgephys
