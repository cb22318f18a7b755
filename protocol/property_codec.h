// The wire form of properties (schema PropertyValue, PropertySet, PropertyChanged,
// PropertyConflict; docs/protocol.md "Properties"): conversions between the FlatBuffers tables
// and protocol/property_value.h. Reading treats the table as untrusted: it only copies what is
// there, then ValidatePropertyValue decides.
//
// Thread-safety: pure functions.
#pragma once

#include <flatbuffers/flatbuffers.h>

#include "edgephys/schema/control_generated.h"
#include "protocol/property_value.h"

namespace edgephys {

// Writes `value` as a PropertyValue table (only the fields of its type).
flatbuffers::Offset<schema::PropertyValue> WritePropertyValue(flatbuffers::FlatBufferBuilder& fbb,
                                                              const PropertyValue& value);
// Reads a PropertyValue table (null: kNone). The type is taken as its number, unknown ones
// included, so that ValidatePropertyValue names them. A vec/quat missing for its type reads
// as not finite (refused). Copies string/bytes.
PropertyValue ReadPropertyValue(const schema::PropertyValue* value);

// Builds a whole ControlMessage{PropertyChanged} for `record` into `fbb` (cleared first).
void BuildPropertyChanged(flatbuffers::FlatBufferBuilder& fbb, const PropertyRecord& record);

}  // namespace edgephys
