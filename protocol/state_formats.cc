#include "protocol/state_formats.h"

#include "protocol/delta_codec.h"
#include "protocol/shared_delta_codec.h"

namespace edgephys {
namespace {

template <typename Decoder>
std::unique_ptr<StateDecoder> Make(const QuantizationParams& params) {
  return std::make_unique<Decoder>(params);
}

struct DecoderRow {
  uint8_t format;
  std::unique_ptr<StateDecoder> (*make)(const QuantizationParams&);
};
constexpr DecoderRow kDecoders[] = {
    {kSharedDeltaStateFormat, Make<SharedDeltaDecoder>},
    {kDeltaStateFormat, Make<DeltaDecoder>},  // the previous default, for one release
};

}  // namespace

std::unique_ptr<StateDecoder> NewStateDecoder(uint8_t format, const QuantizationParams& params) {
  for (const DecoderRow& row : kDecoders) {
    if (row.format == format) return row.make(params);
  }
  return nullptr;
}

}  // namespace edgephys
