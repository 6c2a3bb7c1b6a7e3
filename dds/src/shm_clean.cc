#include "magnav/dds/shm_clean.h"

#include <fcntl.h>
#include <sys/file.h>
#include <sys/stat.h>
#include <unistd.h>

#include <algorithm>
#include <chrono>
#include <filesystem>
#include <regex>
#include <set>
#include <string>
#include <vector>
#include <system_error>

namespace magnav::dds {

namespace {

// True when some process holds a lock on the file (or it cannot be checked).
bool Locked(const std::string& path) {
  const int fd = ::open(path.c_str(), O_RDONLY | O_CLOEXEC);
  if (fd < 0) return true;
  const bool locked = ::flock(fd, LOCK_EX | LOCK_NB) != 0;
  ::close(fd);  // releases our lock, if we took it
  return locked;
}

bool OlderThan(const std::filesystem::path& p, double seconds) {
  struct stat st {};
  if (::stat(p.c_str(), &st) != 0) return false;
  const auto now = std::chrono::system_clock::now().time_since_epoch();
  const double age = std::chrono::duration<double>(now).count() - static_cast<double>(st.st_mtime);
  return age >= seconds;
}

void Remove(const std::filesystem::path& p) {
  std::error_code ec;
  std::filesystem::remove(p, ec);
}

}  // namespace

ShmCleanResult CleanStaleSharedMemory(const std::string& dir, double min_age_s) {
  ShmCleanResult r;
  static const std::regex kSegmentLock("fastrtps_[0-9a-f]{16}_el");
  static const std::regex kPortListenerLock("fastrtps_port[0-9]{1,5}_el");
  std::error_code ec;
  std::filesystem::directory_iterator it(dir, ec), end;
  if (ec) return r;
  std::vector<std::filesystem::path> locks;
  for (; it != end; it.increment(ec)) {
    if (ec) break;
    const std::string name = it->path().filename().string();
    if (std::regex_match(name, kSegmentLock)) locks.push_back(it->path());
    // A marker whose port is gone (removed by hand, or by another process).
    if (name.rfind("magnav_deadport_", 0) == 0 &&
        !std::filesystem::exists(it->path().parent_path() / name.substr(16))) {
      Remove(it->path());
    }
    // Ports: a shorter grace (a listener locks its port right after making it),
    // since a restarted service comes back quickly after its predecessor began.
    if (std::regex_match(name, kPortListenerLock) && OlderThan(it->path(), std::min(min_age_s, 0.5)) &&
        !Locked(it->path().string())) {
      r.dead_ports.push_back(name.substr(0, name.size() - 3));
    }
  }
  for (const std::filesystem::path& lock : locks) {
    if (!OlderThan(lock, min_age_s) || Locked(lock.string())) {
      ++r.in_use;
      continue;
    }
    const std::string name = lock.filename().string();
    Remove(lock.parent_path() / name.substr(0, name.size() - 3));  // the segment
    Remove(lock);
    ++r.segments;
  }
  return r;
}

DeadPortAges AgeDeadPorts(const std::string& dir, const std::vector<std::string>& dead_ports, double wait_s) {
  DeadPortAges a;
  const std::filesystem::path d(dir);
  for (const std::string& port : dead_ports) {
    const std::filesystem::path marker = d / ("magnav_deadport_" + port);
    const int fd = ::open(marker.c_str(), O_WRONLY | O_CREAT | O_EXCL | O_CLOEXEC, 0644);
    if (fd >= 0) {
      ::close(fd);
      ++a.marked_now;
      a.young.push_back(port);
    } else if (OlderThan(marker, wait_s)) {
      a.expired.push_back(port);
    } else {
      a.young.push_back(port);
    }
  }
  return a;
}

std::vector<int> SharedMemoryPorts(const std::string& dir) {
  static const std::regex kPort("fastrtps_port([0-9]{1,5})");
  std::vector<int> out;
  std::error_code ec;
  std::filesystem::directory_iterator it(dir, ec), end;
  if (ec) return out;
  for (; it != end; it.increment(ec)) {
    if (ec) break;
    std::smatch m;
    const std::string name = it->path().filename().string();
    if (std::regex_match(name, m, kPort)) out.push_back(std::stoi(m[1].str()));
  }
  return out;
}

int FreshParticipantId(int domain_id, const std::vector<int>& ports, int max_index) {
  const int base = 7400 + 250 * domain_id;
  std::set<int> used;
  for (const int p : ports) {
    const int offset = p - base;
    if (offset >= 10 && offset < 250) used.insert((offset - 10) / 2);
  }
  for (int id = 0; id < max_index; ++id) {
    if (!used.count(id)) return id;
  }
  return -1;
}

void RemoveDeadPorts(const std::string& dir, const std::vector<std::string>& ports) {
  const std::filesystem::path d(dir);
  for (const std::string& port : ports) {
    if (Locked((d / (port + "_el")).string())) continue;  // a listener came back meanwhile
    Remove(d / port);
    Remove(d / (port + "_el"));
    Remove(d / (port + "_sl"));
    Remove(d / ("sem." + port + "_mutex"));
    Remove(d / ("magnav_deadport_" + port));
  }
}

}  // namespace magnav::dds
