#include "parallel.h"

#include <algorithm>
#include <thread>
#include <vector>

namespace magnav::tracker::internal {

// Number of chunks ParallelFor splits n items into.
std::size_t NumChunks(std::size_t n, int num_threads) {
  return std::max<std::size_t>(1, std::min<std::size_t>(n, static_cast<std::size_t>(std::max(num_threads, 1))));
}

// Runs body(chunk, begin, end) over [0, n) split into NumChunks contiguous
// chunks, chunk 0 in the calling thread. Returns false if any chunk did.
bool ParallelFor(std::size_t n, int num_threads,
                 const std::function<bool(std::size_t, std::size_t, std::size_t)>& body) {
  const std::size_t chunks = NumChunks(n, num_threads);
  if (chunks == 1) return body(0, 0, n);
  std::vector<char> ok(chunks, 0);
  std::vector<std::thread> workers;
  for (std::size_t c = 1; c < chunks; ++c) {
    workers.emplace_back([&, c] { ok[c] = body(c, c * n / chunks, (c + 1) * n / chunks); });
  }
  ok[0] = body(0, 0, n / chunks);
  for (auto& w : workers) w.join();
  return std::all_of(ok.begin(), ok.end(), [](char b) { return b != 0; });
}


}  // namespace magnav::tracker::internal
