// Fast DDS's shared-memory transport leaves its files in /dev/shm when a
// process dies without deleting its participant (kill -9, a crash): data
// segments `fastrtps_<16 hex>` (8 MiB each with magnav's profile) with their
// lock `..._el`. A live owner holds an flock on the lock file; a lock file
// nobody holds belongs to a dead process, and its segment can go (a process
// that still maps it keeps its mapping). Every magnav Node runs this once per
// process at start, so restarts do not pile up dead segments.
//
// Ports (`fastrtps_port<N>` and their locks) are different: a live writer
// keeps sending to a killed reader's port by number until discovery forgets
// the reader (the lease, 3 s in magnav_loopback), and Fast DDS 2.9, when the
// restarted reader gets the same port number and finds the dead port, deletes
// and recreates it while the writer goes on writing into the deleted one (a
// Fast DDS bug, eProsima/Fast-DDS#4728): the restarted service receives
// nothing. Measured in Dds.RestartAfterKill_inverter: 1 run in 7 without data
// when the inverter came back 0.3 s after kill -9; 20 of 20 fine when it came
// back after the lease. So a Node that finds a dead process's port waits out
// the lease first (kZombiePortWait), then removes the dead ports, and only then
// creates its participant.
#pragma once

#include <string>
#include <vector>

namespace magnav::dds {

struct ShmCleanResult {
  int segments = 0;                     // dead segments removed
  int in_use = 0;                       // segments whose lock a live process holds, or too young (kept)
  std::vector<std::string> dead_ports;  // ports whose listener died (not removed: see above)
};

// How long a Node waits after finding a dead port, before removing it and
// joining: the loopback profile's lease (3 s) and a margin.
inline constexpr double kZombiePortWaitS = 4.0;

// Removes the files of dead owners in `dir`. Lock files younger than
// `min_age_s` are left alone (a process that is just starting may not have
// taken its lock yet). Never throws; a file that cannot be removed is skipped.
ShmCleanResult CleanStaleSharedMemory(const std::string& dir = "/dev/shm", double min_age_s = 2.0);

// Removes the files of the dead ports CleanStaleSharedMemory found (the port,
// its locks and its mutex), those whose listener lock is still free now.
void RemoveDeadPorts(const std::string& dir, const std::vector<std::string>& ports);

}  // namespace magnav::dds
