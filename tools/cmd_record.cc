// magnav record: subscribe to a topic and write what arrives as CSV (to a
// file, or '-' for standard output), until a count, a duration or SIGINT; or
// to several topics at once, one CSV per topic in a directory; or every topic
// into one MCAP file (tools/mcap_topics.h).
#include <algorithm>
#include <atomic>
#include <cmath>
#include <chrono>
#include <cstdio>
#include <exception>
#include <filesystem>
#include <functional>
#include <memory>
#include <ctime>
#include <fstream>
#include <iterator>
#include <map>
#include <mutex>
#include <optional>
#include <unistd.h>

#include "commands.h"
#include "magnav/core/csv.h"
#include "magnav/core/gradiometer.h"
#include "magnav/core/units.h"
#include "magnav/dds/node.h"
#include "magnav/dds/repeat_filter.h"
#include "magnav/dds/shutdown.h"
#include "mcap_topics.h"
#include "record_rows.h"

namespace magnav::tools {
namespace {

struct RecordArgs {
  std::vector<std::string> topics;  // one, or several with --output-dir (default: gradiometer)
  std::string output = "-";
  std::string output_dir;
  std::uint64_t count = 0;   // 0 = unlimited
  double duration_s = 0.0;   // 0 = until SIGINT/SIGTERM
  std::string format;        // csv or mcap; "" = from the extension of --output (.mcap), else csv
  std::string compression = "zstd";  // MCAP chunks: zstd, lz4 or none
  std::uint64_t split_size = 0;      // MCAP: a new file once this many bytes are written (0 = never)
  double split_duration_s = 0.0;     // MCAP: a new file after this many seconds (0 = never)
  DdsArgs dds;
};

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

// The whole recording as one MCAP file (or a series with --split-*): a
// schema per type, a channel per topic, every message as the type support's
// CDR with its receive time (log_time) and source time stamp (publish_time).
// Chunks are closed and handed to the system once a second (Flush): after
// kill -9 the temporary holds every chunk but the last second's.
class McapRecorder {
 public:
  McapRecorder(const RecordArgs& a, std::vector<std::string> topics, mcap::KeyValues metadata)
      : path_(a.output), split_size_(a.split_size), split_ns_(static_cast<std::uint64_t>(a.split_duration_s * 1e9)),
        topics_(std::move(topics)), metadata_(std::move(metadata)), counts_(topics_.size()) {
    options_.compression = *mcap::CompressionFromName(a.compression);
    options_.library = std::string("magnav ") + MAGNAV_VERSION;
    ros2_names_ = a.dds.ros2_names || [] {
      const char* e = std::getenv("MAGNAV_ROS2_NAMES");
      return e && std::string(e) == "1";
    }();
    for (auto& c : counts_) c = 0;
    Open();
  }
  ~McapRecorder() {
    try {
      Close();
    } catch (const std::exception&) {
    }
  }
  template <class M>
  void Write(std::size_t topic, const M& m, const dds::fdds::SampleInfo& info) {
    const std::string cdr = ToCdr(m);
    const std::uint64_t log = static_cast<std::uint64_t>(
        std::chrono::duration_cast<std::chrono::nanoseconds>(std::chrono::system_clock::now().time_since_epoch()).count());
    const std::int64_t src = info.source_timestamp.to_ns();
    std::lock_guard<std::mutex> lk(mu_);
    if (!writer_) return;
    if (!first_log_) first_log_ = log;
    if ((split_size_ > 0 && writer_->size_estimate() >= split_size_) || (split_ns_ > 0 && log - *first_log_ >= split_ns_)) {
      Rotate();
      first_log_ = log;
    }
    writer_->Write(channels_[topic], seq_[topic]++, log, src > 0 ? static_cast<std::uint64_t>(src) : log, cdr.data(),
                   cdr.size());
    ++counts_[topic];
  }
  std::uint64_t count(std::size_t topic) const { return counts_[topic].load(); }
  void Flush() {
    std::lock_guard<std::mutex> lk(mu_);
    if (writer_) writer_->Flush();
  }
  void Close() {
    std::lock_guard<std::mutex> lk(mu_);
    if (!writer_) return;
    std::unique_ptr<mcap::Writer> w = std::move(writer_);
    w->Close();
    Report(*w);
  }

 private:
  std::string NextPath() const {
    if (index_ == 0) return path_;
    const std::size_t dot = path_.rfind('.');
    const std::size_t slash = path_.rfind('/');
    const bool has_ext = dot != std::string::npos && (slash == std::string::npos || dot > slash);
    char n[16];
    std::snprintf(n, sizeof n, "_%04d", index_);
    return has_ext ? path_.substr(0, dot) + n + path_.substr(dot) : path_ + n;
  }
  void Open() {
    writer_ = std::make_unique<mcap::Writer>(NextPath(), options_);
    mcap::KeyValues meta = metadata_;
    meta.emplace_back("file_index", std::to_string(index_));
    writer_->AddMetadata("magnav_recording", meta);
    std::map<std::string, std::uint16_t> schema_ids;
    channels_.clear();
    seq_.assign(topics_.size(), 0);
    for (const std::string& t : topics_) {
      const std::string type = TypeNameOf(t);
      auto it = schema_ids.find(type);
      if (it == schema_ids.end()) it = schema_ids.emplace(type, writer_->AddSchema(type, "omgidl", MagnavIdl())).first;
      mcap::KeyValues meta_c = WriterQosMetadata(t);
      meta_c.emplace_back("dds_type", type);
      channels_.push_back(writer_->AddChannel(it->second, (ros2_names_ ? "rt/magnav/" : "magnav/") + t, "cdr", meta_c));
    }
  }
  void Rotate() {
    std::unique_ptr<mcap::Writer> w = std::move(writer_);
    w->Close();
    Report(*w);
    ++index_;
    Open();
  }
  void Report(const mcap::Writer& w) const {
    std::fprintf(stderr, "record: wrote %s (%llu messages, %llu bytes, %s chunks)\n", w.path().c_str(),
                 static_cast<unsigned long long>(w.statistics().message_count),
                 static_cast<unsigned long long>(w.bytes_written()),
                 options_.compression == mcap::Compression::kNone ? "uncompressed" : mcap::CompressionName(options_.compression));
  }

  std::string path_;
  std::uint64_t split_size_, split_ns_;
  std::vector<std::string> topics_;
  mcap::KeyValues metadata_;
  mcap::WriterOptions options_;
  bool ros2_names_ = false;
  std::mutex mu_;
  std::unique_ptr<mcap::Writer> writer_;
  int index_ = 0;
  std::optional<std::uint64_t> first_log_;
  std::vector<std::uint16_t> channels_;
  std::vector<std::uint32_t> seq_;
  std::vector<std::atomic<std::uint64_t>> counts_;
};

// The command line as given (from /proc/self/cmdline), for the recording's metadata.
std::string CommandLine() {
  std::ifstream in("/proc/self/cmdline", std::ios::binary);
  std::string all((std::istreambuf_iterator<char>(in)), std::istreambuf_iterator<char>());
  std::string out;
  std::size_t start = 0;
  while (start < all.size()) {
    std::size_t end = all.find('\0', start);
    if (end == std::string::npos) end = all.size();
    std::string arg = all.substr(start, end - start);
    if (arg.find_first_of(" '\"\\t") != std::string::npos) arg = "'" + arg + "'";
    if (!out.empty()) out += " ";
    out += arg;
    start = end + 1;
  }
  return out;
}

std::string UtcNow() {
  const std::time_t t = std::time(nullptr);
  char b[32];
  std::strftime(b, sizeof b, "%Y-%m-%dT%H:%M:%SZ", std::gmtime(&t));
  return b;
}

// One topic being recorded: its reader (type-erased) and its sink (CSV), or
// its count in the MCAP recorder.
struct Recording {
  std::string topic;
  std::unique_ptr<Sink> sink;
  std::shared_ptr<void> reader;
  std::function<std::uint64_t()> lost;
  std::function<int()> matched;  // writers matched now
  int matched_said = 0;          // as last logged
  std::shared_ptr<dds::RepeatFilter> repeats;
  std::function<std::uint64_t()> written;
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
  r.matched = [reader] { return reader->stats().matched.load(); };
  r.reader = reader;
  r.written = [sink] { return sink->count(); };
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

template <class M>
Recording SubscribeMcap(dds::Node& node, const std::string& topic, std::size_t index, McapRecorder* rec,
                        std::uint64_t count) {
  Recording r;
  r.topic = topic;
  r.repeats = std::make_shared<dds::RepeatFilter>();
  r.repeats->SetLogName("record: magnav/" + topic + " key");
  dds::RepeatFilter* repeats = r.repeats.get();
  std::shared_ptr<dds::Reader<M>> reader = node.CreateReader<M>([rec, index, count, repeats](const M& m, const auto& info) {
    if ((count == 0 || rec->count(index) < count) && repeats->First(m, info)) rec->Write(index, m, info);
  });
  r.lost = [reader] { return reader->stats().lost.load(); };
  r.matched = [reader] { return reader->stats().matched.load(); };
  r.reader = reader;
  r.written = [rec, index] { return rec->count(index); };
  return r;
}

bool IsMcap(const RecordArgs& a) {
  if (!a.format.empty()) return a.format == "mcap";
  return a.output.size() > 5 && a.output.compare(a.output.size() - 5, 5, ".mcap") == 0;
}

mcap::KeyValues RecordingMetadata(const RecordArgs& a, const dds::Node& node) {
  const char* env_participant = std::getenv("MAGNAV_DDS_PARTICIPANT");
  const char* env_profiles = std::getenv("MAGNAV_DDS_PROFILES");
  std::string topics;
  for (const std::string& t : a.topics) topics += (topics.empty() ? std::string() : std::string(",")) + t;
  return {{"domain_id", std::to_string(node.domain_id())},
          {"participant_profile", !a.dds.participant_profile.empty() ? a.dds.participant_profile
                                  : env_participant                  ? env_participant
                                                                     : "magnav_loopback"},
          {"dds_profiles_file", !a.dds.profiles_file.empty() ? a.dds.profiles_file : env_profiles ? env_profiles : ""},
          {"magnav_version", MAGNAV_VERSION},
          {"command_line", CommandLine()},
          {"start_time_utc", UtcNow()},
          {"topics", topics.empty() ? "gradiometer" : topics}};
}

void Run(const RecordArgs& a) {
  std::vector<std::string> topics = a.topics.empty() ? std::vector<std::string>{"gradiometer"} : a.topics;
  if (std::find(topics.begin(), topics.end(), "all") != topics.end()) topics = AllTopics();
  std::sort(topics.begin(), topics.end());
  topics.erase(std::unique(topics.begin(), topics.end()), topics.end());
  const bool mcap_out = IsMcap(a);
  if (mcap_out) {
    if (a.output == "-" || !a.output_dir.empty()) {
      throw InputError("record: MCAP goes to one file: give --output FILE.mcap (not - or --output-dir)");
    }
    if (!mcap::CompressionFromName(a.compression)) throw InputError("record: --compression must be zstd, lz4 or none");
  } else {
    if (a.split_size > 0 || a.split_duration_s > 0) throw InputError("record: --split-size/--split-duration go with MCAP output");
    if (topics.size() > 1 && a.output_dir.empty()) {
      throw InputError("record: several topics need --output-dir DIR (one TOPIC.csv each) or --output FILE.mcap");
    }
    if (!a.output_dir.empty() && a.output != "-") throw InputError("record: give --output or --output-dir, not both");
  }
  if (!a.output_dir.empty()) {
    std::error_code ec;
    std::filesystem::create_directories(a.output_dir, ec);
    if (ec || !std::filesystem::is_directory(a.output_dir)) {
      throw InputError("--output-dir: cannot create directory '" + a.output_dir + "'");
    }
  }
  dds::InstallShutdownHandlers();
  dds::Node node(a.dds.ToNodeOptions("magnav_record"));
  std::unique_ptr<McapRecorder> mcap_rec;
  if (mcap_out) mcap_rec = std::make_unique<McapRecorder>(a, topics, RecordingMetadata(a, node));
  std::vector<Recording> rec;
  for (std::size_t i = 0; i < topics.size(); ++i) {
    const std::string& t = topics[i];
    if (mcap_rec) {
      WithTopicType(t, [&](auto m) { rec.push_back(SubscribeMcap<decltype(m)>(node, t, i, mcap_rec.get(), a.count)); });
    } else {
      rec.push_back(Subscribe(node, t, a.output_dir.empty() ? a.output : a.output_dir + "/" + t + ".csv", a.count));
    }
  }
  // Until SIGINT/SIGTERM, the duration, or every topic's --count.
  const auto start = std::chrono::steady_clock::now();
  auto next_flush = start + std::chrono::seconds(1);
  while (!dds::ShutdownRequested()) {
    // Once a second the rows so far go to the temporary: after kill -9 it
    // holds all but the last second's (docs/RELIABILITY.md).
    // Producers coming and going, as discovery sees them (a log line, and what
    // a script waits for before it starts a producer's input).
    for (Recording& r : rec) {
      const int m = r.matched();
      if (m != r.matched_said) {
        std::fprintf(stderr, "record: magnav/%s: %d writer(s) matched\n", r.topic.c_str(), m);
        r.matched_said = m;
      }
    }
    if (std::chrono::steady_clock::now() >= next_flush) {
      for (Recording& r : rec) {
        if (r.sink) r.sink->Flush();
      }
      if (mcap_rec) mcap_rec->Flush();
      next_flush += std::chrono::seconds(1);
    }
    if (a.count > 0 && std::all_of(rec.begin(), rec.end(), [&](const Recording& r) { return r.written() >= a.count; })) {
      break;
    }
    if (a.duration_s > 0 &&
        std::chrono::steady_clock::now() - start > std::chrono::duration<double>(a.duration_s)) {
      break;
    }
    dds::WaitForShutdown(std::chrono::milliseconds(20));
  }
  std::vector<std::uint64_t> lost(rec.size());
  for (std::size_t i = 0; i < rec.size(); ++i) {
    lost[i] = rec[i].lost();
    rec[i].lost = nullptr;  // it holds the reader too
    rec[i].matched = nullptr;
    rec[i].reader.reset();  // the reader is deleted: no callback after this
    if (rec[i].sink) rec[i].sink->Close();
  }
  if (mcap_rec) mcap_rec->Close();
  for (std::size_t i = 0; i < rec.size(); ++i) {
    Recording& r = rec[i];
    if (lost[i] > 0) {
      std::fprintf(stderr, "record: %llu sample(s) lost on magnav/%s\n", static_cast<unsigned long long>(lost[i]),
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
    std::fprintf(stderr, "recorded %llu %s sample(s)\n", static_cast<unsigned long long>(r.written()), r.topic.c_str());
  }
}

}  // namespace

void AddRecordCommand(CLI::App& app) {
  auto args = std::make_shared<RecordArgs>();
  CLI::App* sub = app.add_subcommand("record", "Write what arrives on magnav topics as CSV, or every topic into one MCAP file");
  sub->add_option("--topic", args->topics,
                  "gradiometer (default), dipole_fix, track, magnetometer, vessel_nav, sensor_position, map_fix, or all; "
                  "several (repeated, or comma-separated) with --output-dir or --output FILE.mcap")
      ->delimiter(',')
      ->check(CLI::IsMember(TopicChoices()));
  sub->add_option("--output", args->output,
                  "CSV file, or - for standard output. The rows go to OUTPUT.tmp-PID-N, renamed to OUTPUT when "
                  "recording stops (SIGINT/SIGTERM, --count, --duration or an error): OUTPUT only ever holds "
                  "whole rows; after kill -9 the rows so far are in the temporary");
  sub->add_option("--output-dir", args->output_dir,
                  "several topics: a directory (made if missing) with one TOPIC.csv per topic, each written as --output");
  sub->add_option("--format", args->format,
                  "csv or mcap (default: mcap when --output ends in .mcap, else csv). MCAP: every --topic in one file "
                  "(schema omgidl = idl/magnav.idl, messages cdr as on the wire, chunk and message indexes, summary; "
                  "docs/PROTOCOL.md), written to OUTPUT.tmp-PID-N and renamed when recording stops")
      ->check(CLI::IsMember({"csv", "mcap"}));
  sub->add_option("--compression", args->compression, "MCAP chunk compression: zstd (default), lz4 or none")
      ->check(CLI::IsMember({"zstd", "lz4", "none"}));
  sub->add_option("--split-size", args->split_size,
                  "MCAP: start a new file (OUTPUT_0001.mcap, _0002, ...) once this many bytes are written (0 = never)");
  sub->add_option("--split-duration", args->split_duration_s,
                  "MCAP: start a new file after this many seconds of recording (0 = never)")
      ->check(CLI::NonNegativeNumber);
  sub->add_option("--count", args->count, "stop after this many samples (of every topic; 0 = no limit)");
  sub->add_option("--duration", args->duration_s, "stop after this many seconds (0 = until SIGINT/SIGTERM)");
  AddDdsOptions(*sub, &args->dds);
  sub->callback([args] { Run(*args); });
}

}  // namespace magnav::tools
