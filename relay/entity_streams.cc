#include "relay/entity_streams.h"

#include "protocol/shared_delta_codec.h"
#include "protocol/state_formats.h"
#include "relay/replication.h"

namespace edgephys {

std::unique_ptr<StateStream> NewEntityStream(const ReplicationConfig& config) {
  if (config.plugin != nullptr) return config.plugin->NewStream(config);
  auto params = MakeQuantizationParams(QuantizationOf(config));
  if (!params.ok()) params = MakeQuantizationParams(QuantizationConfig{});
  return NewStateStream(StateFormatOf(config), *params,
                        {config.position_threshold_m, config.rotation_threshold_deg});
}

uint8_t StateFormatOf(const ReplicationConfig& config) {
  if (config.plugin != nullptr) return config.plugin->state_format();
  return config.shared_encoding ? kSharedDeltaStateFormat : kDeltaStateFormat;
}

}  // namespace edgephys
