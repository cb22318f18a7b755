#include "protocol/state_formats.h"

#include "protocol/delta_codec.h"
#include "protocol/shared_delta_codec.h"

namespace edgephys {
namespace {

template <typename Decoder>
std::unique_ptr<StateDecoder> MakeDecoder(const QuantizationParams& params) {
  return std::make_unique<Decoder>(params);
}

template <typename Stream>
std::unique_ptr<StateStream> MakeStream(const QuantizationParams& params,
                                        const StreamThresholds& thresholds) {
  return std::make_unique<Stream>(params, thresholds);
}

struct FormatRow {
  uint8_t format;
  std::unique_ptr<StateStream> (*stream)(const QuantizationParams&, const StreamThresholds&);
  std::unique_ptr<StateDecoder> (*decoder)(const QuantizationParams&);
};
constexpr FormatRow kFormats[] = {
    {kSharedDeltaStateFormat, MakeStream<SharedDeltaStateStream>, MakeDecoder<SharedDeltaDecoder>},
    // The previous default, for one release.
    {kDeltaStateFormat, MakeStream<DeltaStateStream>, MakeDecoder<DeltaDecoder>},
};

const FormatRow* RowOf(uint8_t format) {
  for (const FormatRow& row : kFormats) {
    if (row.format == format) return &row;
  }
  return nullptr;
}

}  // namespace

std::unique_ptr<StateDecoder> NewStateDecoder(uint8_t format, const QuantizationParams& params) {
  const FormatRow* row = RowOf(format);
  return row != nullptr ? row->decoder(params) : nullptr;
}

std::unique_ptr<StateStream> NewStateStream(uint8_t format, const QuantizationParams& params,
                                            const StreamThresholds& thresholds) {
  const FormatRow* row = RowOf(format);
  return row != nullptr ? row->stream(params, thresholds) : nullptr;
}

}  // namespace edgephys
