// Progress of a long command (magnav replay, magnav track): on a terminal one
// line redrawn four times a second (done of the total, rate, time left);
// otherwise a plain line every 10 s (none for a run shorter than that).
#pragma once

#include <unistd.h>

#include <chrono>
#include <cmath>
#include <cstdio>
#include <string>
#include <utility>

#include "magnav/core/csv.h"

namespace magnav::cli {

class Progress {
 public:
  // `prefix` starts each line ("replay"), `unit` names what is counted
  // ("samples"); total 0: open-ended (no "of N", no time left). Lines go to
  // `out` (stdout, or stderr where stdout is data).
  Progress(std::string prefix, std::string unit, std::size_t total, std::FILE* out = stdout)
      : prefix_(std::move(prefix)), unit_(std::move(unit)), total_(total), out_(out),
        tty_(isatty(fileno(out)) != 0) {}
  ~Progress() { Done(); }
  Progress(const Progress&) = delete;
  Progress& operator=(const Progress&) = delete;

  // `n` done so far; `stage` (optional) says what is being done.
  void Update(std::size_t n, const std::string& stage = "") {
    const auto now = std::chrono::steady_clock::now();
    if (now < next_) return;
    next_ = now + (tty_ ? std::chrono::milliseconds(250) : std::chrono::milliseconds(10000));
    const double elapsed = std::chrono::duration<double>(now - start_).count();
    if (elapsed < 0.25) return;  // no rate from the first items (and no line at all before 10 s off a terminal)
    const double rate = static_cast<double>(n) / elapsed;
    std::string line = prefix_ + ": " + (stage.empty() ? "" : stage + ", ") + std::to_string(n) +
                       (total_ > 0 ? " of " + std::to_string(total_) : "") + " " + unit_ + ", " +
                       FormatNumber(std::round(rate)) + "/s";
    if (total_ > 0 && rate > 0 && n <= total_) {
      line += ", " + FormatNumber(std::round(static_cast<double>(total_ - n) / rate)) + " s left";
    }
    std::fprintf(out_, tty_ ? "\r%-78s" : "%s\n", line.c_str());
    std::fflush(out_);
    shown_ = true;
  }
  // A stage whose length is not known (one line, at once off a terminal too).
  void Say(const std::string& what) {
    std::fprintf(out_, tty_ ? "\r%-78s" : "%s\n", (prefix_ + ": " + what).c_str());
    std::fflush(out_);
    shown_ = true;
  }
  // Clears the terminal line.
  void Done() {
    if (tty_ && shown_) std::fprintf(out_, "\r%-78s\r", "");
    shown_ = false;
  }

 private:
  std::string prefix_, unit_;
  std::size_t total_;
  std::FILE* out_;
  bool tty_, shown_ = false;
  std::chrono::steady_clock::time_point start_ = std::chrono::steady_clock::now(), next_ = start_;
};

}  // namespace magnav::cli
