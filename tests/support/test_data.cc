#include "test_data.h"

#include <cstdlib>
#include <filesystem>
#include <stdexcept>

#include <unistd.h>

namespace magnav::testing {

std::string TestDataDir() {
  if (const char* env = std::getenv("MAGNAV_TEST_DATA"); env && *env) return env;
  return MAGNAV_SOURCE_TEST_DATA;
}

std::string ReferencePath(const std::string& name) { return TestDataDir() + "/reference/" + name; }

int TestDomainId() { return 10 + static_cast<int>(::getpid() % 200); }

std::string TempDir() {
  // A new, empty directory every time (mkdtemp): a name made of the pid
  // could be one a reused pid of an earlier run left behind, files and all.
  std::string tmpl = (std::filesystem::temp_directory_path() / "magnav_test_XXXXXX").string();
  if (::mkdtemp(tmpl.data()) == nullptr) throw std::runtime_error("cannot create a temporary directory");
  return tmpl;
}

}  // namespace magnav::testing
