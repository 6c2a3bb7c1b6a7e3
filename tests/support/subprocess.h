// A child process for tests: spawn with extra environment variables, read its
// standard output, signal it, wait for its exit code with a timeout.
#pragma once

#include <chrono>
#include <map>
#include <string>
#include <vector>

#include <sys/types.h>

namespace magnav::testing {

class Subprocess {
 public:
  // argv[0] is the executable path. stdout is captured; stderr too when
  // merge_stderr is set.
  Subprocess(const std::vector<std::string>& argv, const std::map<std::string, std::string>& env = {},
             bool merge_stderr = false);
  ~Subprocess();  // SIGKILLs a child still running
  Subprocess(const Subprocess&) = delete;
  Subprocess& operator=(const Subprocess&) = delete;

  std::string ReadLine();  // one line of stdout ("" at end)
  std::string ReadAll();   // the rest of stdout
  void Signal(int sig);
  // Exit code; -1 on timeout or death by a signal.
  int Wait(std::chrono::milliseconds timeout);

 private:
  pid_t pid_ = -1;
  int out_fd_ = -1;
  bool waited_ = false;
};

// Runs a command to completion and returns {exit code, stdout+stderr}.
std::pair<int, std::string> RunCommand(const std::vector<std::string>& argv,
                                       const std::map<std::string, std::string>& env = {},
                                       std::chrono::milliseconds timeout = std::chrono::seconds(60));

}  // namespace magnav::testing
