#include "magnav/dds/shm_clean.h"

#include <fcntl.h>
#include <sys/file.h>
#include <sys/stat.h>
#include <unistd.h>

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
  static const std::regex kPortLock("fastrtps_port[0-9]{1,5}_(el|sl)");
  std::error_code ec;
  std::filesystem::directory_iterator it(dir, ec), end;
  if (ec) return r;
  std::vector<std::filesystem::path> locks;
  for (; it != end; it.increment(ec)) {
    if (ec) break;
    const std::string name = it->path().filename().string();
    if (std::regex_match(name, kSegmentLock) || std::regex_match(name, kPortLock)) locks.push_back(it->path());
  }
  std::set<std::string> done;
  for (const std::filesystem::path& lock : locks) {
    const std::string name = lock.filename().string();
    const std::string base = name.substr(0, name.size() - 3);  // without _el / _sl
    if (!done.insert(base).second) continue;
    // A port has two lock files (listener: _el, senders: _sl): dead only when neither is held.
    bool dead = true;
    for (const char* suffix : {"_el", "_sl"}) {
      const std::filesystem::path l = lock.parent_path() / (base + suffix);
      if (std::filesystem::exists(l, ec) && (!OlderThan(l, min_age_s) || Locked(l.string()))) dead = false;
    }
    if (!dead) {
      ++r.in_use;
      continue;
    }
    Remove(lock.parent_path() / base);
    Remove(lock.parent_path() / (base + "_el"));
    Remove(lock.parent_path() / (base + "_sl"));
    if (name.rfind("fastrtps_port", 0) == 0) {
      Remove(lock.parent_path() / ("sem." + base + "_mutex"));
      ++r.ports;
    } else {
      ++r.segments;
    }
  }
  return r;
}

}  // namespace magnav::dds
