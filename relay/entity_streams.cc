#include "relay/entity_streams.h"

#include "relay/entity.h"
#include "relay/replication.h"

namespace edgephys {
namespace {

StreamNeed FromUpdateNeed(DeltaEncoder::UpdateNeed need) {
  switch (need) {
    case DeltaEncoder::UpdateNeed::kSend: return StreamNeed::kSend;
    case DeltaEncoder::UpdateNeed::kAckedWithin: return StreamNeed::kSettled;
    case DeltaEncoder::UpdateNeed::kInFlightWithin: return StreamNeed::kSkip;
  }
  return StreamNeed::kSend;
}

std::unique_ptr<EntityStream> MakeShared(const ReplicationConfig& c, const QuantizationParams& p) {
  return std::make_unique<SharedDeltaEntityStream>(c, p);
}

std::unique_ptr<EntityStream> MakeDelta(const ReplicationConfig& c, const QuantizationParams& p) {
  return std::make_unique<DeltaEntityStream>(c, p);
}

bool Always(const ReplicationConfig&) { return true; }

// The relay's formats, first match wins.
struct FormatRow {
  uint8_t id;
  bool (*selected)(const ReplicationConfig&);
  std::unique_ptr<EntityStream> (*make)(const ReplicationConfig&, const QuantizationParams&);
};
constexpr FormatRow kFormats[] = {
    {kSharedDeltaStateFormat, UsesSharedEncoding, MakeShared},
    {kDeltaStateFormat, Always, MakeDelta},  // the previous default, for one release
};

const FormatRow& RowOf(const ReplicationConfig& config) {
  for (const FormatRow& row : kFormats) {
    if (row.selected(config)) return row;
  }
  return kFormats[std::size(kFormats) - 1];
}

}  // namespace

SharedDeltaEntityStream::SharedDeltaEntityStream(const ReplicationConfig& config,
                                                 const QuantizationParams& params)
    : CodecEntityStream(config.position_threshold_m, config.rotation_threshold_deg, params) {}

StreamNeed SharedDeltaEntityStream::Want(const Entity& e, double now, double resend_after_s,
                                         uint8_t*) {
  if (e.shared == nullptr) return StreamNeed::kSend;
  return FromUpdateNeed(codec_.Need(e.id, *e.shared, e.state, position_threshold_m_,
                                    rotation_threshold_deg_, now, resend_after_s));
}

bool SharedDeltaEntityStream::Add(const Entity& e, uint8_t) {
  // The room codes the body once for every receiver.
  return e.shared != nullptr && e.prepared_valid && codec_.Add(e.id, *e.shared);
}

void SharedDeltaEntityStream::Count(bool sent, RelayCounters& counters) {
  const SharedDeltaStreamStats& st = codec_.stats();
  if (sent) {
    RelayCounters::Inc(counters.shared_bodies_cached, st.cache_hits - hits_counted_);
    RelayCounters::Inc(counters.shared_bodies_coded,
                       (st.entities - entities_counted_) - (st.cache_hits - hits_counted_));
  }
  hits_counted_ = st.cache_hits;
  entities_counted_ = st.entities;
}

DeltaEntityStream::DeltaEntityStream(const ReplicationConfig& config,
                                     const QuantizationParams& params)
    : CodecEntityStream(config.position_threshold_m, config.rotation_threshold_deg, params) {}

StreamNeed DeltaEntityStream::Want(const Entity& e, double now, double resend_after_s, uint8_t*) {
  return FromUpdateNeed(codec_.Need(e.id, e.state, position_threshold_m_, rotation_threshold_deg_,
                                    now, resend_after_s));
}

bool DeltaEntityStream::Add(const Entity& e, uint8_t) {
  // The room quantised the state once for every receiver.
  return codec_.Add(e.state, e.prepared_valid ? &e.prepared : nullptr);
}

std::unique_ptr<EntityStream> NewEntityStream(const ReplicationConfig& config) {
  if (config.plugin != nullptr) return config.plugin->NewStream(config);
  auto params = MakeQuantizationParams(QuantizationOf(config));
  if (!params.ok()) params = MakeQuantizationParams(QuantizationConfig{});
  return RowOf(config).make(config, *params);
}

uint8_t StateFormatOf(const ReplicationConfig& config) {
  if (config.plugin != nullptr) return config.plugin->state_format();
  return RowOf(config).id;
}

}  // namespace edgephys
