// The relay's own rigid-body state formats as EntityStreams (relay/entity_stream.h), and the
// registry that picks one for a room's ReplicationConfig.
//
// A format is one row of kFormats in entity_streams.cc: its id, when a room uses it, and its
// stream; its codec lives in protocol/ (format 9: shared_delta_codec.h, format 2:
// delta_codec.h) with its tests, and the client's decoder is a row of
// protocol/state_formats.cc. Adding a format: a codec file with its test, and the two rows.
//
// Thread-safety: the streams belong to one receiver (its room's thread); the functions are pure.
#pragma once

#include <cstdint>
#include <memory>

#include "protocol/delta_codec.h"
#include "protocol/shared_delta_codec.h"
#include "relay/entity_stream.h"

namespace edgephys {

struct ReplicationConfig;

// What the built-in streams share: the selective-sync thresholds and a codec whose payload and
// acknowledgement calls they forward (DeltaEncoder and SharedDeltaStream name them alike).
template <typename Codec>
class CodecEntityStream : public EntityStream {
 public:
  void Begin(std::span<uint8_t> out, uint32_t time_ms) override { codec_.Begin(out, time_ms); }
  size_t count() const override { return codec_.count(); }
  size_t Finish() override { return codec_.Finish(); }
  void OnSent(uint16_t sequence, double now) override { codec_.OnSent(sequence, now); }
  void OnAcked(uint16_t sequence) override { codec_.OnPacketAcked(sequence); }
  void Forget(uint32_t entity_id) override { codec_.Forget(entity_id); }

 protected:
  CodecEntityStream(float position_threshold_m, float rotation_threshold_deg,
                    const QuantizationParams& params)
      : position_threshold_m_(position_threshold_m),
        rotation_threshold_deg_(rotation_threshold_deg),
        codec_(params) {}
  float position_threshold_m_;
  float rotation_threshold_deg_;
  Codec codec_;
};

// Format 9: records reference versions the room coded once for all receivers (Entity::shared,
// Room::PrepareStates); per receiver only the choice of reference and a bit copy.
class SharedDeltaEntityStream final : public CodecEntityStream<SharedDeltaStream> {
 public:
  SharedDeltaEntityStream(const ReplicationConfig& config, const QuantizationParams& params);
  StreamNeed Want(const Entity& e, double now, double resend_after_s, uint8_t* fields) override;
  void Prefetch(uint32_t slot) const override { codec_.Prefetch(slot); }
  bool Add(const Entity& e, uint8_t fields) override;
  // Adds the bodies this stream's sent payloads took from the room's cache and coded itself
  // (edgephys_shared_bodies_{cached,coded}_total).
  void Count(bool sent, RelayCounters& counters) override;

 private:
  uint64_t hits_counted_ = 0;      // codec_'s stats already added to the counters
  uint64_t entities_counted_ = 0;
};

// Format 2: quantized deltas against this receiver's own acknowledged baselines.
class DeltaEntityStream final : public CodecEntityStream<DeltaEncoder> {
 public:
  DeltaEntityStream(const ReplicationConfig& config, const QuantizationParams& params);
  StreamNeed Want(const Entity& e, double now, double resend_after_s, uint8_t* fields) override;
  bool Add(const Entity& e, uint8_t fields) override;
};

// The stream a receiver in a room with `config` gets: the plug-in's if it has one, else the
// first row of kFormats that `config` selects. A quantisation MakeQuantizationParams refuses
// (the relay's flags and the admin API refuse them first) is replaced by the default one.
std::unique_ptr<EntityStream> NewEntityStream(const ReplicationConfig& config);
// The format id rooms with `config` announce in Joined.
uint8_t StateFormatOf(const ReplicationConfig& config);

}  // namespace edgephys
