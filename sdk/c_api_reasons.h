// The reason table behind edgephys_reason_name and the text the C API puts in the detail of
// REJECTED, ERROR and DISCONNECTED events (include/edgephys/edgephys_reasons.h). Internal to
// sdk/. Static storage; thread-safe (read-only).
#pragma once

#include <cstdint>
#include <string_view>

namespace edgephys::capi {

// The table's name of `code` for an event of `event_type` ("unknown" outside the table).
const char* ReasonName(uint32_t event_type, uint32_t code);
// The table's meaning of `code` for an event of `event_type`: text for a person ("unknown
// reason" outside the table).
std::string_view ReasonText(uint32_t event_type, uint32_t code);

}  // namespace edgephys::capi
