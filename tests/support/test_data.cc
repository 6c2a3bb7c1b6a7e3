#include "test_data.h"

#include <cstdlib>
#include <filesystem>
#include <stdexcept>
#include <string>

#include <fcntl.h>
#include <sys/file.h>
#include <unistd.h>

namespace magnav::testing {

std::string TestDataDir() {
  if (const char* env = std::getenv("MAGNAV_TEST_DATA"); env && *env) return env;
  return MAGNAV_SOURCE_TEST_DATA;
}

std::string ReferencePath(const std::string& name) { return TestDataDir() + "/reference/" + name; }

namespace {

// Claims a DDS domain for this process: the first of the even domains
// 10, 12, …, 228 (from one chosen by the pid) whose lock file in
// $TMPDIR/magnav-test-domains this process can flock; the lock is held until
// the process exits, and the odd domain after it (StockRelay::InputDomain)
// comes with it. tests/support/dds_test_lib.sh claims from the same files,
// so tests run side by side (ctest -j) never share a domain — a pid modulo a
// range did, now and then: a relay then forwarded another test's samples.
int ClaimDomain() {
  constexpr int kFirst = 10, kCount = 110;
  const std::filesystem::path dir = std::filesystem::temp_directory_path() / "magnav-test-domains";
  std::error_code ec;
  std::filesystem::create_directories(dir, ec);
  for (int i = 0; i < kCount; ++i) {
    const int domain = kFirst + 2 * static_cast<int>((::getpid() + i) % kCount);
    const std::string lock = (dir / (std::to_string(domain) + ".lock")).string();
    const int fd = ::open(lock.c_str(), O_RDWR | O_CREAT | O_CLOEXEC, 0666);
    if (fd < 0) continue;
    if (::flock(fd, LOCK_EX | LOCK_NB) == 0) return domain;  // fd kept open: the claim lasts the process
    ::close(fd);
  }
  throw std::runtime_error("no free DDS test domain: every lock in " + dir.string() + " is held");
}

}  // namespace

int TestDomainId() {
  static const int domain = ClaimDomain();
  return domain;
}

std::string TempDir() {
  // A new, empty directory every time (mkdtemp): a name made of the pid
  // could be one a reused pid of an earlier run left behind, files and all.
  std::string tmpl = (std::filesystem::temp_directory_path() / "magnav_test_XXXXXX").string();
  if (::mkdtemp(tmpl.data()) == nullptr) throw std::runtime_error("cannot create a temporary directory");
  return tmpl;
}

}  // namespace magnav::testing
