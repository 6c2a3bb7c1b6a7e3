// The libFuzzer driver of one entry point (entries.h), chosen at build time
// by MAGNAV_FUZZ_ENTRY (fuzz/CMakeLists.txt).
#include <cstddef>
#include <cstdint>

#include <spdlog/spdlog.h>

#include "entries.h"

extern "C" int LLVMFuzzerInitialize(int* /*argc*/, char*** /*argv*/) {
  spdlog::set_level(spdlog::level::off);  // SampleDoor logs each refusal once
  return 0;
}

extern "C" int LLVMFuzzerTestOneInput(const std::uint8_t* data, std::size_t size) {
  magnav::fuzz::MAGNAV_FUZZ_ENTRY(data, size);
  return 0;
}
