// magnav record: subscribe to a topic and write what arrives as CSV (to a
// file, or '-' for standard output), until a count, a duration or SIGINT; or
// to several topics at once, one CSV per topic in a directory.
#include <algorithm>
#include <atomic>
#include <cmath>
#include <chrono>
#include <cstdio>
#include <exception>
#include <filesystem>
#include <functional>
#include <memory>
#include <mutex>

#include "commands.h"
#include "magnav/core/csv.h"
#include "magnav/core/gradiometer.h"
#include "magnav/core/units.h"
#include "magnav/dds/node.h"
#include "magnav/dds/repeat_filter.h"
#include "magnav/dds/shutdown.h"

namespace magnav::tools {
namespace {

struct RecordArgs {
  std::vector<std::string> topics;  // one, or several with --output-dir (default: gradiometer)
  std::string output = "-";
  std::string output_dir;
  std::uint64_t count = 0;   // 0 = unlimited
  double duration_s = 0.0;   // 0 = until SIGINT/SIGTERM
  DdsArgs dds;
};

std::string N(double v) { return FormatNumber(v); }

template <std::size_t K>
void Append(std::vector<std::string>& f, const std::array<double, K>& a) {
  for (double v : a) f.push_back(N(v));
}

// Every field of the message is written (covariances as 9 row-major columns,
// with sigma_x..z = the roots of their diagonals for `magnav evaluate`).
void AppendNamed(std::vector<std::string>& h, const std::string& prefix, const char* const* names, int n) {
  for (int i = 0; i < n; ++i) h.push_back(prefix + names[i]);
}
const char* const kXyz[] = {"x", "y", "z"};
const char* const kCov[] = {"xx", "xy", "xz", "yx", "yy", "yz", "zx", "zy", "zz"};

std::vector<std::string> Header(const std::string& topic) {
  std::vector<std::string> h;
  if (topic == "gradiometer") {
    h = {"t", "sensor_id", "seq"};
    for (std::string& c : GradiometerDataColumns()) h.push_back(std::move(c));
    h.push_back("sigma_B");
    h.push_back("sigma_T");
    return h;
  }
  if (topic == "dipole_fix") {
    h = {"t", "sensor_id", "seq", "method", "dipole_x", "dipole_y", "dipole_z", "valid", "reason", "cond",
         "has_moment"};
    AppendNamed(h, "m_", kXyz, 3);
    AppendNamed(h, "sigma_", kXyz, 3);
    AppendNamed(h, "cov_", kCov, 9);
    return h;
  }
  if (topic == "magnetometer") return {"t", "sensor_id", "seq", "B_x", "B_y", "B_z"};
  if (topic == "vessel_nav") return {"t", "x", "y", "sigma"};
  if (topic == "map_fix") {
    // covariance (north, east) m², row-major, and its roots.
    return {"t", "vehicle_id", "method", "lat", "lon", "score", "sigma_north_m", "sigma_east_m", "cov_nn", "cov_ne",
            "cov_en", "cov_ee", "status"};
  }
  if (topic == "sensor_position") {
    // The columns of `magnav localize`'s output, with the estimate's time first.
    return {"t", "sensor_id", "x", "y", "z", "sigma_x", "sigma_y", "crlb_x", "crlb_y"};
  }
  h = {"t", "track_id", "x", "y", "z", "vx", "vy", "vz", "heading", "turn_rate", "sigma_x", "sigma_y", "sigma_z"};
  AppendNamed(h, "cov_", kCov, 9);
  AppendNamed(h, "moment_body_", kXyz, 3);
  AppendNamed(h, "moment_cov_", kCov, 9);
  h.push_back("num_sensors");
  h.push_back("usable");
  return h;
}

// Roots of a row-major 3×3 covariance's diagonal; empty when it is all zero
// (unknown).
void AppendSigmas(std::vector<std::string>& f, const std::array<double, 9>& cov) {
  const bool known = std::any_of(cov.begin(), cov.end(), [](double v) { return v != 0.0; });
  for (int i = 0; i < 3; ++i) f.push_back(known ? N(std::sqrt(std::max(0.0, cov[4 * i]))) : "");
}

std::vector<std::string> Row(const dds::msg::MagnetometerSample& m) {
  std::vector<std::string> f = {FormatNanosAsSeconds(m.stamp_ns()), std::to_string(m.sensor_id()), std::to_string(m.seq())};
  Append(f, m.B());
  return f;
}

// A GNSS file row (t,x,y,sigma) as `magnav localize --gnss` reads it.
std::vector<std::string> Row(const dds::msg::VesselNav& m) {
  return {FormatNanosAsSeconds(m.stamp_ns()), N(m.position()[0]), N(m.position()[1]),
          N(std::max(m.sigma_position()[0], m.sigma_position()[1]))};
}

std::vector<std::string> Row(const dds::msg::SensorPositionEstimate& m) {
  std::vector<std::string> f = {FormatNanosAsSeconds(m.stamp_ns()), std::to_string(m.sensor_id())};
  Append(f, m.position());
  f.push_back(N(std::sqrt(std::max(0.0, m.covariance()[0]))));
  f.push_back(N(std::sqrt(std::max(0.0, m.covariance()[4]))));
  f.push_back(N(std::sqrt(std::max(0.0, m.crlb()[0]))));
  f.push_back(N(std::sqrt(std::max(0.0, m.crlb()[4]))));
  return f;
}

// MapFix.status as written in the CSV ("" = unknown: a publisher older than the field).
const char* MapFixStatusName(dds::msg::MapFixStatus s) {
  switch (s) {
    case dds::msg::MAP_FIX_STATUS_OK: return "ok";
    case dds::msg::MAP_FIX_STATUS_LOST: return "lost";
    case dds::msg::MAP_FIX_STATUS_OFF_MAP: return "off_map";
    default: return "";
  }
}

std::vector<std::string> Row(const dds::msg::MapFix& m) {
  std::vector<std::string> f = {FormatNanosAsSeconds(m.stamp_ns()), std::to_string(m.vehicle_id()), m.method_name().c_str(),
                                N(m.lat_deg()), N(m.lon_deg()), N(m.score()),
                                N(std::sqrt(std::max(0.0, m.covariance()[0]))),
                                N(std::sqrt(std::max(0.0, m.covariance()[3])))};
  Append(f, m.covariance());
  f.push_back(MapFixStatusName(m.status()));
  return f;
}

std::vector<std::string> Row(const dds::msg::GradiometerSample& m) {
  std::vector<std::string> f = {FormatNanosAsSeconds(m.stamp_ns()), std::to_string(m.sensor_id()), std::to_string(m.seq())};
  Append(f, m.sensor_position());
  Append(f, m.B());
  Append(f, m.T());
  f.push_back(N(m.sigma_B()));
  f.push_back(N(m.sigma_T()));
  return f;
}

std::vector<std::string> Row(const dds::msg::DipoleFix& m) {
  std::vector<std::string> f = {FormatNanosAsSeconds(m.stamp_ns()), std::to_string(m.sensor_id()),
                                std::to_string(m.sample_seq()), std::to_string(static_cast<int>(m.method()))};
  Append(f, m.position());
  f.push_back(m.valid() ? "1" : "0");
  f.push_back(m.reason().c_str());
  f.push_back(N(m.condition_number()));
  f.push_back(m.has_moment() ? "1" : "0");
  Append(f, m.moment());
  AppendSigmas(f, m.covariance());
  Append(f, m.covariance());
  return f;
}

std::vector<std::string> Row(const dds::msg::TrackEstimate& m) {
  std::vector<std::string> f = {FormatNanosAsSeconds(m.stamp_ns()), std::to_string(m.track_id())};
  Append(f, m.position());
  Append(f, m.velocity());
  f.push_back(N(m.heading()));
  f.push_back(N(m.turn_rate()));
  AppendSigmas(f, m.covariance());
  Append(f, m.covariance());
  Append(f, m.moment_body());
  Append(f, m.moment_covariance());
  f.push_back(std::to_string(m.num_sensors()));
  f.push_back(m.usable() ? "1" : "0");
  return f;
}

class Sink {
 public:
  Sink(const std::string& path, const std::vector<std::string>& header) {
    if (path == "-") {
      Print(header);
    } else {
      writer_ = std::make_unique<CsvWriter>(path, header);
    }
  }
  // Left by an error: what was recorded is kept (every row is whole).
  ~Sink() {
    try {
      Close();
    } catch (const std::exception&) {
    }
  }
  // A row that arrives after Close (from a receive thread, while recording
  // stops) is dropped.
  void Write(const std::vector<std::string>& f) {
    std::lock_guard<std::mutex> lk(mu_);
    if (closed_) return;
    if (writer_) {
      writer_->WriteRow(f);
    } else {
      Print(f);
    }
    ++count_;
  }
  std::uint64_t count() const { return count_.load(); }
  void Flush() {
    std::lock_guard<std::mutex> lk(mu_);
    if (writer_ && !closed_) writer_->Flush();
  }
  void Close() {
    std::lock_guard<std::mutex> lk(mu_);
    closed_ = true;
    if (writer_) writer_->Close();
  }

 private:
  void Print(const std::vector<std::string>& f) {
    for (std::size_t i = 0; i < f.size(); ++i) std::fputs((i ? "," + f[i] : f[i]).c_str(), stdout);
    std::fputc('\n', stdout);
    std::fflush(stdout);
  }
  std::mutex mu_;
  std::unique_ptr<CsvWriter> writer_;
  bool closed_ = false;
  std::atomic<std::uint64_t> count_{0};
};

// One topic being recorded: its reader (type-erased) and its sink.
struct Recording {
  std::string topic;
  std::unique_ptr<Sink> sink;
  std::shared_ptr<void> reader;
  std::function<std::uint64_t()> lost;
  std::shared_ptr<dds::RepeatFilter> repeats;
};

template <class M>
Recording Subscribe(dds::Node& node, const std::string& topic, const std::string& path, std::uint64_t count) {
  Recording r;
  r.topic = topic;
  r.sink = std::make_unique<Sink>(path, Header(topic));
  Sink* sink = r.sink.get();
  // A message seen before (a restarted producer's history: same key, seq and
  // time) is written once.
  r.repeats = std::make_shared<dds::RepeatFilter>();
  r.repeats->SetLogName("record: magnav/" + topic + " key");
  dds::RepeatFilter* repeats = r.repeats.get();
  std::shared_ptr<dds::Reader<M>> reader = node.CreateReader<M>([sink, count, repeats](const M& m, const auto& info) {
    if ((count == 0 || sink->count() < count) && repeats->First(m, info)) sink->Write(Row(m));
  });
  r.lost = [reader] { return reader->stats().lost.load(); };
  r.reader = reader;
  return r;
}

Recording Subscribe(dds::Node& node, const std::string& topic, const std::string& path, std::uint64_t count) {
  if (topic == "gradiometer") return Subscribe<dds::msg::GradiometerSample>(node, topic, path, count);
  if (topic == "dipole_fix") return Subscribe<dds::msg::DipoleFix>(node, topic, path, count);
  if (topic == "magnetometer") return Subscribe<dds::msg::MagnetometerSample>(node, topic, path, count);
  if (topic == "vessel_nav") return Subscribe<dds::msg::VesselNav>(node, topic, path, count);
  if (topic == "sensor_position") return Subscribe<dds::msg::SensorPositionEstimate>(node, topic, path, count);
  if (topic == "map_fix") return Subscribe<dds::msg::MapFix>(node, topic, path, count);
  return Subscribe<dds::msg::TrackEstimate>(node, topic, path, count);
}

const std::vector<std::string> kTopics = {"gradiometer",  "dipole_fix",      "track",  "magnetometer",
                                          "vessel_nav",   "sensor_position", "map_fix"};

void Run(const RecordArgs& a) {
  std::vector<std::string> topics = a.topics.empty() ? std::vector<std::string>{"gradiometer"} : a.topics;
  if (std::find(topics.begin(), topics.end(), "all") != topics.end()) topics = kTopics;
  std::sort(topics.begin(), topics.end());
  topics.erase(std::unique(topics.begin(), topics.end()), topics.end());
  if (topics.size() > 1 && a.output_dir.empty()) {
    throw InputError("record: several topics need --output-dir DIR (one TOPIC.csv each)");
  }
  if (!a.output_dir.empty() && a.output != "-") throw InputError("record: give --output or --output-dir, not both");
  if (!a.output_dir.empty()) {
    std::error_code ec;
    std::filesystem::create_directories(a.output_dir, ec);
    if (ec || !std::filesystem::is_directory(a.output_dir)) {
      throw InputError("--output-dir: cannot create directory '" + a.output_dir + "'");
    }
  }
  dds::InstallShutdownHandlers();
  dds::Node node(a.dds.ToNodeOptions("magnav_record"));
  std::vector<Recording> rec;
  for (const std::string& t : topics) {
    rec.push_back(Subscribe(node, t, a.output_dir.empty() ? a.output : a.output_dir + "/" + t + ".csv", a.count));
  }
  // Until SIGINT/SIGTERM, the duration, or every topic's --count.
  const auto start = std::chrono::steady_clock::now();
  auto next_flush = start + std::chrono::seconds(1);
  while (!dds::ShutdownRequested()) {
    // Once a second the rows so far go to the temporary: after kill -9 it
    // holds all but the last second's (docs/RELIABILITY.md).
    if (std::chrono::steady_clock::now() >= next_flush) {
      for (Recording& r : rec) r.sink->Flush();
      next_flush += std::chrono::seconds(1);
    }
    if (a.count > 0 && std::all_of(rec.begin(), rec.end(), [&](const Recording& r) { return r.sink->count() >= a.count; })) {
      break;
    }
    if (a.duration_s > 0 &&
        std::chrono::steady_clock::now() - start > std::chrono::duration<double>(a.duration_s)) {
      break;
    }
    dds::WaitForShutdown(std::chrono::milliseconds(20));
  }
  for (Recording& r : rec) {
    const std::uint64_t lost = r.lost();
    r.lost = nullptr;  // it holds the reader too
    r.reader.reset();  // the reader is deleted: no callback after this
    r.sink->Close();
    if (lost > 0) {
      std::fprintf(stderr, "record: %llu sample(s) lost on magnav/%s\n", static_cast<unsigned long long>(lost),
                   r.topic.c_str());
    }
    if (r.repeats->repeats() > 0) {
      std::fprintf(stderr, "record: %llu repeated message(s) on magnav/%s written once (same key, seq and time)\n",
                   static_cast<unsigned long long>(r.repeats->repeats()), r.topic.c_str());
    }
    if (r.repeats->missing() > 0 || r.repeats->restarts() > 0) {
      std::fprintf(stderr, "record: %llu message(s) on magnav/%s missing by sequence number, %llu step(s) back\n",
                   static_cast<unsigned long long>(r.repeats->missing()), r.topic.c_str(),
                   static_cast<unsigned long long>(r.repeats->restarts()));
    }
    std::fprintf(stderr, "recorded %llu %s sample(s)\n", static_cast<unsigned long long>(r.sink->count()),
                 r.topic.c_str());
  }
}

}  // namespace

void AddRecordCommand(CLI::App& app) {
  auto args = std::make_shared<RecordArgs>();
  CLI::App* sub = app.add_subcommand("record", "Write what arrives on a magnav topic as CSV");
  sub->add_option("--topic", args->topics,
                  "gradiometer (default), dipole_fix, track, magnetometer, vessel_nav, sensor_position, map_fix, or all; "
                  "several (repeated, or comma-separated) with --output-dir")
      ->delimiter(',')
      ->check(CLI::IsMember({"gradiometer", "dipole_fix", "track", "magnetometer", "vessel_nav", "sensor_position",
                             "map_fix", "all"}));
  sub->add_option("--output", args->output,
                  "CSV file, or - for standard output. The rows go to OUTPUT.tmp-PID-N, renamed to OUTPUT when "
                  "recording stops (SIGINT/SIGTERM, --count, --duration or an error): OUTPUT only ever holds "
                  "whole rows; after kill -9 the rows so far are in the temporary");
  sub->add_option("--output-dir", args->output_dir,
                  "several topics: a directory (made if missing) with one TOPIC.csv per topic, each written as --output");
  sub->add_option("--count", args->count, "stop after this many samples (of every topic; 0 = no limit)");
  sub->add_option("--duration", args->duration_s, "stop after this many seconds (0 = until SIGINT/SIGTERM)");
  AddDdsOptions(*sub, &args->dds);
  sub->callback([args] { Run(*args); });
}

}  // namespace magnav::tools
