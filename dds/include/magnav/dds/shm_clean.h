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
// back after the lease. Waiting out the lease before joining (what magnav did
// next) was not enough: a restarted magnav-tracker still received nothing in
// 1 of 10 runs (Dds.RestartAfterKill_tracker, 2026-11-25). So a Node that
// finds a dead process's port on its domain does not take that port number
// again: it joins at once with a participant index that no shared-memory
// port of the domain uses, alive or dead (FreshParticipantId; its ports are
// new files, never a dead one's), and removes the dead ports only once the
// lease is over (kZombiePortWaitS after the first process saw them dead: a
// marker file `magnav_deadport_<port>` in /dev/shm holds that time), when no
// writer sends to them any more: at once if a process finds them marked long
// enough ago, else in the background of the process that marked them.
#pragma once

#include <string>
#include <vector>

namespace magnav::dds {

struct ShmCleanResult {
  int segments = 0;                     // dead segments removed
  int in_use = 0;                       // segments whose lock a live process holds, or too young (kept)
  std::vector<std::string> dead_ports;  // ports whose listener died (not removed: see above)
};

// How long after finding a dead port a Node removes it: the loopback
// profile's lease (3 s) and a margin.
inline constexpr double kZombiePortWaitS = 4.0;

// Port numbers of every shared-memory port in `dir` (`fastrtps_port<N>`),
// alive or dead.
std::vector<int> SharedMemoryPorts(const std::string& dir = "/dev/shm");

// The lowest participant index whose ports (Fast DDS's well-known ports:
// 7400 + 250·domain + 10 + 2·index for discovery, + 11 + 2·index for data)
// are none of `ports`; -1 if the domain has no free index below max_index.
int FreshParticipantId(int domain_id, const std::vector<int>& ports, int max_index = 32);

// Removes the files of dead owners in `dir`. Lock files younger than
// `min_age_s` are left alone (a process that is just starting may not have
// taken its lock yet). Never throws; a file that cannot be removed is skipped.
ShmCleanResult CleanStaleSharedMemory(const std::string& dir = "/dev/shm", double min_age_s = 2.0);

// The dead ports found, split by how long ago a process first saw them dead
// (their marker; a port without one is marked now): `expired` were marked at
// least wait_s ago and may be removed, `young` not yet; `marked_now` of the
// young were first seen by this call.
struct DeadPortAges {
  std::vector<std::string> expired, young;
  int marked_now = 0;
};
DeadPortAges AgeDeadPorts(const std::string& dir, const std::vector<std::string>& dead_ports, double wait_s);

// Removes the files of the dead ports CleanStaleSharedMemory found (the port,
// its locks, its mutex and its marker), those whose listener lock is still
// free now.
void RemoveDeadPorts(const std::string& dir, const std::vector<std::string>& ports);

}  // namespace magnav::dds
