// The rigid-body state formats of the product, by id: the relay's sending end (a StateStream
// per receiver) and the SDK's receiving end (a StateDecoder per room) of each.
//
// One row each in state_formats.cc: 9 (shared delta, the relay's default) and 2 (the previous
// default, kept for one release). The relay picks the id its rooms send (relay/entity_streams.h)
// and announces it in Joined; the client builds the decoder of that id. Soft bodies (format 11,
// protocol/soft_delta_stream.h) go beside the stream and decode into particles, not rows here.
// The benchmark emulations are plug-ins (relay/entity_stream.h, client/state_decoder_plugin.h)
// that only the load generator and tests link.
//
// Adding a format: its codec file (encoder, StateStream, StateDecoder) with its test, and a
// row in state_formats.cc.
//
// Thread-safety: pure functions. Each stream and decoder belongs to one receiver.
#pragma once

#include <cstdint>
#include <memory>

#include "protocol/quantize.h"
#include "protocol/state_codec.h"
#include "protocol/state_stream.h"

namespace edgephys {

// A new decoder of `format` for a room quantised by `params`; nullptr if the SDK does not
// decode `format`.
std::unique_ptr<StateDecoder> NewStateDecoder(uint8_t format, const QuantizationParams& params);

// A new sending end of `format` for one receiver of a room quantised by `params`; nullptr if
// the product has no such format.
std::unique_ptr<StateStream> NewStateStream(uint8_t format, const QuantizationParams& params,
                                            const StreamThresholds& thresholds);

}  // namespace edgephys
