// The stream-merge flags of the services that merge several sensors' streams
// in time (magnav-localizer, magnav-tracker): --merge, --idle-timeout,
// --reorder-delay, into a magnav::StreamMergeOptions (core/stream_merge.h).
#pragma once

#include <string>

#include <CLI/CLI.hpp>

#include "magnav/core/stream_merge.h"

namespace magnav::cli {

// `streams` names the streams in the help text (e.g. "each sensor, the GNSS").
inline void AddMergeOptions(CLI::App& app, StreamMergeOptions* out, const std::string& streams) {
  app.add_option_function<std::string>(
         "--merge",
         [out](const std::string& v) { out->merge = v == "delay" ? StreamMerge::kReorderDelay : StreamMerge::kWatermark; },
         "how the streams (" + streams + ") are merged in time: watermark (an item waits until every live stream "
         "has reached its time; a quiet stream stops holding the others after --idle-timeout; restarts and unpaced "
         "replays merge exactly) or delay (an item waits until one --reorder-delay newer has arrived)")
      ->check(CLI::IsMember({"watermark", "delay"}))
      ->default_str(out->merge == StreamMerge::kWatermark ? "watermark" : "delay");
  app.add_option("--idle-timeout", out->idle_timeout_s,
                 "watermark: a stream silent this long (wall clock, s) stops holding the others")
      ->capture_default_str();
  app.add_option("--reorder-delay", out->reorder_delay_s,
                 "delay: hold samples this long (sample time, s) to order the streams")
      ->capture_default_str();
}

}  // namespace magnav::cli
