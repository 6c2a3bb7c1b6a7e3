// FuzzMcap: the MCAP reader (tools/mcap) on any bytes (entries.h).
#include <cstdlib>
#include <string>

#include "entries.h"
#include "magnav/core/error.h"
#include "magnav/mcap/mcap.h"

namespace magnav::fuzz {

void FuzzMcap(const std::uint8_t* data, std::size_t size) {
  const std::string bytes(reinterpret_cast<const char*>(data), size);
  mcap::ReaderLimits limits;
  // A chunk may claim at most 64 MiB here (the fuzzer's memory limit), as a
  // file's 1 GiB does for the programs.
  limits.max_chunk_bytes = 64u << 20;
  limits.max_record_bytes = 64u << 20;
  try {
    std::uint64_t seen = 0;
    const mcap::ReadSummary s = mcap::ReadBytes(
        "fuzz.mcap", bytes,
        [&](const mcap::Message& m, const mcap::ReadSummary& sum) {
          // Invariant: a message handed on has its channel (and its schema, if any).
          const mcap::Channel* c = mcap::FindChannel(sum, m.channel_id);
          if (!c) std::abort();
          if (c->schema_id != 0 && !mcap::FindSchema(sum, c->schema_id)) std::abort();
          ++seen;
        },
        limits);
    if (s.messages != seen) std::abort();
  } catch (const InputError&) {
  }
}

}  // namespace magnav::fuzz
