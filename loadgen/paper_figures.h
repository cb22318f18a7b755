// The figures the Decoupled Edge Physics paper publishes for the scenarios the load generator
// repeats, keyed by the size it measured; 0 for a size it did not measure. Scenarios report
// their own measurement beside these (and the ratio to them).
#pragma once

#include <cstdint>

namespace edgephys::loadgen {

// Relay egress in the relay-compare experiment, bytes/s: the paper's relay and its Photon-style
// baseline, for 32 .. 512 objects.
double PaperRelayBytesPerS(uint32_t objects);
double PaperPhotonBytesPerS(uint32_t objects);
// PhyS egress per client for the MultiObject scene Obj_N, Mb/s (10^6 bit/s).
double PaperObjMbitPerS(uint32_t objects);
// PhyS egress per client for the soft-body scene Bunny_N, Mb/s (10^6 bit/s).
double PaperBunnyMbitPerS(uint32_t bunnies);

}  // namespace edgephys::loadgen
