#include "test_data.h"

#include <cstdlib>
#include <filesystem>

#include <unistd.h>

namespace magnav::testing {

std::string TestDataDir() {
  if (const char* env = std::getenv("MAGNAV_TEST_DATA"); env && *env) return env;
  return MAGNAV_SOURCE_TEST_DATA;
}

std::string ReferencePath(const std::string& name) { return TestDataDir() + "/reference/" + name; }

int TestDomainId() { return 10 + static_cast<int>(::getpid() % 200); }

std::string TempDir() {
  static int counter = 0;
  const auto dir = std::filesystem::temp_directory_path() /
                   ("magnav_test_" + std::to_string(::getpid()) + "_" + std::to_string(counter++));
  std::filesystem::create_directories(dir);
  return dir.string();
}

}  // namespace magnav::testing
