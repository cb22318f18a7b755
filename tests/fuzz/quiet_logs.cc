// libFuzzer's initializer for the targets that drive the relay and the client (packet_fuzz,
// message_fuzz): logging off, since both log every refused datagram and would bury the
// fuzzer's own output. Linked into those targets by tests/fuzz/CMakeLists.txt.
#include <spdlog/spdlog.h>

extern "C" int LLVMFuzzerInitialize(int*, char***) {
  spdlog::set_level(spdlog::level::off);
  return 0;
}
