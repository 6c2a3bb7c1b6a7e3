// Fast DDS's shared-memory transport leaves its files in /dev/shm when a
// process dies without deleting its participant (kill -9, a crash): segments
// `fastrtps_<16 hex>` with their lock `..._el`, and ports `fastrtps_port<N>`
// with `..._el` / `..._sl` and `sem.fastrtps_port<N>_mutex`. A live owner
// holds an flock on the lock file; a lock file nobody holds belongs to a dead
// process. This is what `fastdds shm clean` does; every magnav Node runs it
// once per process at start, so a restarted service does not leave (or run
// into) its predecessor's files.
#pragma once

#include <string>

namespace magnav::dds {

struct ShmCleanResult {
  int segments = 0;  // dead segments removed
  int ports = 0;     // dead ports removed
  int in_use = 0;    // lock files held by a live process (kept)
};

// Removes the files of dead owners in `dir`. Lock files younger than
// `min_age_s` are left alone (a process that is just starting may not have
// taken its lock yet). Never throws; a file that cannot be removed is skipped.
ShmCleanResult CleanStaleSharedMemory(const std::string& dir = "/dev/shm", double min_age_s = 2.0);

}  // namespace magnav::dds
