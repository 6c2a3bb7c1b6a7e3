// The tracker's one way of using several threads: a loop split into
// contiguous chunks (num_threads of TrackerOptions).
#pragma once

#include <cstddef>
#include <functional>

namespace magnav::tracker::internal {

// Number of chunks ParallelFor splits n items into.
std::size_t NumChunks(std::size_t n, int num_threads);

// Runs body(chunk, begin, end) over [0, n) split into NumChunks contiguous
// chunks, chunk 0 in the calling thread. Returns false if any chunk did.
bool ParallelFor(std::size_t n, int num_threads,
                 const std::function<bool(std::size_t, std::size_t, std::size_t)>& body);

}  // namespace magnav::tracker::internal
