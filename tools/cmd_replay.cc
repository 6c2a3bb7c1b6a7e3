// magnav replay: publish a gradiometer file onto magnav/gradiometer, or a
// localize measurements file onto magnav/magnetometer (one MagnetometerSample
// per row) with, optionally, a GNSS file onto magnav/vessel_nav (one VesselNav
// per row), paced by their time columns (or as fast as the reliable streams
// allow). The two localize streams go out merged in time order, a fix before
// the samples of the same time. Or a map-matching run (`--map-path`, the
// k,ins_lat,ins_lon,meas_nT files of `magnav match`): per point a VesselNav
// (NAV_INS, geodetic = the INS lat/lon) and a MagnetometerSample whose |B| is
// the map's reference field plus the measured anomaly, with the same stamp
// (docs/PROTOCOL.md), one point every --step-period seconds. Or an MCAP
// recording (`magnav record --output FILE.mcap`): its sensor topics (or those
// of --topic) as recorded, paced by their receive times (log_time).
#include <unistd.h>

#include <algorithm>
#include <chrono>
#include <cstdio>
#include <cmath>
#include <memory>
#include <thread>
#include <unordered_map>

#include "commands.h"
#include "magnav/cli/progress.h"
#include "magnav/core/csv.h"
#include "magnav/core/error.h"
#include "magnav/core/gradiometer.h"
#include "magnav/core/units.h"
#include "magnav/dds/convert.h"
#include "magnav/dds/convert_localizer.h"
#include "magnav/dds/node.h"
#include "magnav/dds/shutdown.h"
#include "magnav/mapmatch/path.h"
#include "magnav/mcap/mcap.h"
#include "mcap_topics.h"

namespace magnav::tools {
namespace {

struct ReplayArgs {
  std::string input, magnetometer, gnss, map_path, meas_column = "meas_nT";
  double reference_field_nT = std::nan("");
  double step_period_s = 1.0;
  std::uint32_t vehicle_id = 0;
  double speed = 1.0;           // time factor; 0 = as fast as possible
  bool loop = false;            // gradiometer file: over and over until stopped
  int wait_readers = 1;
  double wait_s = 10.0;
  double settle_s = 0.25;       // after the readers matched, before the first sample
  std::vector<std::string> topics;  // MCAP input: topics to send (default: the sensor topics)
  DdsArgs dds;
};

// One timed message of the localize streams.
struct LocalizeEvent {
  double t_s;
  bool is_fix;
  dds::msg::MagnetometerSample sample;
  dds::msg::VesselNav fix;
};

std::vector<LocalizeEvent> ReadLocalizeEvents(const std::string& measurements, const std::string& gnss) {
  std::vector<LocalizeEvent> out;
  const CsvTable m = CsvTable::Read(measurements);
  const double sigma = m.param_number("sigma_B_T").value_or(0.0);  // 0 = not stated
  const double z = m.param_number("vessel_z_m").value_or(std::nan(""));
  const std::size_t t = m.column("t"), id = m.column("sensor_id"), bx = m.column("B_x"), by = m.column("B_y"),
                    bz = m.column("B_z");
  std::unordered_map<std::uint32_t, std::uint64_t> seq;
  for (std::size_t i = 0; i < m.num_rows(); ++i) {
    localizer::MagSample s;
    s.t_s = m.number(i, t);
    s.sensor_id = m.uint32(i, id);
    s.B_T = {m.number(i, bx), m.number(i, by), m.number(i, bz)};
    out.push_back({s.t_s, false, dds::ToMsg(s, seq[s.sensor_id]++, sigma), {}});  // position unknown (NaN)
  }
  if (!gnss.empty()) {
    const CsvTable g = CsvTable::Read(gnss);
    const std::size_t gt = g.column("t"), x = g.column("x"), y = g.column("y"), s = g.column("sigma");
    for (std::size_t i = 0; i < g.num_rows(); ++i) {
      localizer::GnssFix f;
      f.t_s = g.number(i, gt);
      f.p_xy_m = {g.number(i, x), g.number(i, y)};
      f.sigma_m = g.number(i, s);
      out.push_back({f.t_s, true, {}, dds::ToMsg(f, /*vessel_id=*/0, z)});
    }
  }
  // Time order; at equal times the fix first, else file order.
  std::stable_sort(out.begin(), out.end(), [](const LocalizeEvent& a, const LocalizeEvent& b) {
    return a.t_s < b.t_s || (a.t_s == b.t_s && a.is_fix && !b.is_fix);
  });
  return out;
}

// After the readers matched: this side has matched them, but a reader may not
// yet have matched this writer (its discovery runs on its own), and a VOLATILE
// reader of another vendor then drops the first samples and starts from a
// later heartbeat. TRANSIENT_LOCAL readers are repaired from the history and
// need no settling (docs/INTEROP.md).
void Settle(const ReplayArgs& a) {
  if (a.wait_readers > 0 && a.settle_s > 0) std::this_thread::sleep_for(std::chrono::duration<double>(a.settle_s));
}

void WarnIfNotAcknowledged(bool acked) {
  if (!acked) {
    std::fprintf(stderr,
                 "replay: warning: not every matched reader acknowledged every sample within 10 s of the end (a reader "
                 "left, or is too slow): it may have missed the last samples\n");
  }
}

void RunLocalizeStreams(const ReplayArgs& a, const std::vector<LocalizeEvent>& events, bool with_nav) {
  dds::InstallShutdownHandlers();
  dds::Node node(a.dds.ToNodeOptions("magnav_replay"));
  auto samples = node.CreateWriter<dds::msg::MagnetometerSample>();
  auto fixes = node.CreateWriter<dds::msg::VesselNav>();
  samples->SetFlowControl(500, std::chrono::seconds(10));
  fixes->SetFlowControl(500, std::chrono::seconds(10));
  const auto wait = std::chrono::milliseconds(static_cast<long>(a.wait_s * 1000));
  if (a.wait_readers > 0 && (!samples->WaitForMatched(a.wait_readers, wait) ||
                             (with_nav && !fixes->WaitForMatched(a.wait_readers, wait)))) {
    throw InputError("replay: no reader of magnav/magnetometer (and magnav/vessel_nav) appeared within " +
                     FormatNumber(a.wait_s) + " s (domain " + std::to_string(node.domain_id()) + ")");
  }
  Settle(a);
  const auto t0 = std::chrono::steady_clock::now();
  const double file_t0 = events.empty() ? 0.0 : events.front().t_s;
  std::size_t sent = 0, sent_fixes = 0;
  for (const LocalizeEvent& e : events) {
    if (dds::ShutdownRequested()) break;
    if (a.speed > 0) {
      std::this_thread::sleep_until(t0 + std::chrono::duration<double>((e.t_s - file_t0) / a.speed));
    }
    if (!(e.is_fix ? fixes->Write(e.fix) : samples->Write(e.sample))) {
      throw InputError("replay: the middleware refused a sample");
    }
    ++(e.is_fix ? sent_fixes : sent);
  }
  const bool acked = samples->WaitForAcknowledgments(std::chrono::seconds(10));
  WarnIfNotAcknowledged(fixes->WaitForAcknowledgments(std::chrono::seconds(10)) && acked);
  std::printf("replayed %zu magnetometer samples and %zu vessel_nav fixes on domain %d\n", sent, sent_fixes,
              node.domain_id());
}

// A map-matching run: events in path order, the VesselNav before the sample.
std::vector<LocalizeEvent> ReadMapRunEvents(const ReplayArgs& a) {
  if (!(std::isfinite(a.reference_field_nT) && a.reference_field_nT > 0.0)) {
    throw InputError("replay: --map-path needs --reference-field (the map's reference field, nT)");
  }
  if (!(a.step_period_s > 0.0)) throw InputError("replay: --step-period must be > 0");
  const mapmatch::MatchPath p = mapmatch::ReadMatchPath(a.map_path, a.meas_column);
  std::vector<LocalizeEvent> out;
  for (std::size_t i = 0; i < p.size(); ++i) {
    const double t = static_cast<double>(i) * a.step_period_s;
    const std::uint64_t stamp = SecondsToNanos(t);
    LocalizeEvent fix{t, true, {}, dds::InsNavMsg(a.vehicle_id, stamp, p.lat_deg[i], p.lon_deg[i])};
    LocalizeEvent sample{t, false, dds::AnomalySampleMsg(a.vehicle_id, stamp, i, p.measured_nT[i], a.reference_field_nT), {}};
    out.push_back(fix);
    out.push_back(sample);
  }
  return out;
}

// ---- MCAP recordings -------------------------------------------------------

struct McapEvent {
  std::size_t topic;  // index into the senders
  std::uint64_t log_time;
  std::string data;
};

// One topic's writer; Send decodes the recorded CDR, shifts it for a --loop
// pass and writes it.
struct McapSender {
  virtual ~McapSender() = default;
  virtual bool WaitForMatched(int n, std::chrono::milliseconds t) = 0;
  virtual bool Send(const std::string& cdr, std::uint64_t dt_ns, int pass) = 0;
  virtual bool WaitForAcknowledgments() = 0;
  // Checks one recorded message (before anything is sent) and notes its
  // key's sequence span and its stamp; false if it is not CDR of the type.
  virtual bool Check(const std::string& cdr, std::uint64_t* stamp_ns) = 0;
  std::string topic;
  std::uint64_t sent = 0;
};

template <class M>
struct TypedMcapSender : McapSender {
  std::unique_ptr<dds::Writer<M>> writer;
  std::unordered_map<std::uint32_t, std::pair<std::int64_t, std::int64_t>> seq_span;  // key -> (min, max)
  bool WaitForMatched(int n, std::chrono::milliseconds t) override { return writer->WaitForMatched(n, t); }
  bool WaitForAcknowledgments() override { return writer->WaitForAcknowledgments(std::chrono::seconds(10)); }
  bool Check(const std::string& cdr, std::uint64_t* stamp_ns) override {
    M m;
    if (!FromCdr(cdr, &m)) return false;
    *stamp_ns = m.stamp_ns();
    const std::int64_t s = SeqOf(m);
    if (s >= 0) {
      auto [it, fresh] = seq_span.try_emplace(KeyOf(m), s, s);
      if (!fresh) {
        it->second.first = std::min(it->second.first, s);
        it->second.second = std::max(it->second.second, s);
      }
    }
    return true;
  }
  bool Send(const std::string& cdr, std::uint64_t dt_ns, int pass) override {
    M m;
    if (!FromCdr(cdr, &m)) return false;
    if (pass > 0) {
      m.stamp_ns(m.stamp_ns() + dt_ns);
      auto it = seq_span.find(KeyOf(m));
      if (it != seq_span.end()) {
        ShiftSeq(m, static_cast<std::uint64_t>(pass) * static_cast<std::uint64_t>(it->second.second - it->second.first + 1));
      }
    }
    ++sent;
    return writer->Write(m);
  }
};

void RunMcap(const ReplayArgs& a) {
  std::vector<std::string> wanted = a.topics;
  if (std::find(wanted.begin(), wanted.end(), "all") != wanted.end()) wanted = AllTopics();
  auto selected = [&](const std::string& t) {
    return wanted.empty() ? IsSensorTopic(t) : std::find(wanted.begin(), wanted.end(), t) != wanted.end();
  };
  dds::InstallShutdownHandlers();
  dds::Node node(a.dds.ToNodeOptions("magnav_replay"));
  std::vector<std::unique_ptr<McapSender>> senders;
  std::unordered_map<std::uint16_t, std::size_t> sender_of;  // channel -> sender; absent = not sent
  std::unordered_map<std::uint16_t, bool> seen;
  std::vector<McapEvent> events;
  std::uint64_t stamp_min = UINT64_MAX, stamp_max = 0, skipped = 0;
  const mcap::ReadSummary summary = mcap::Read(a.input, [&](const mcap::Message& m, const mcap::ReadSummary& s) {
    if (!seen[m.channel_id]) {
      seen[m.channel_id] = true;
      const mcap::Channel* c = mcap::FindChannel(s, m.channel_id);
      const std::string topic = c->message_encoding == "cdr" ? ShortTopic(c->topic) : "";
      if (!topic.empty() && selected(topic)) {
        std::size_t index = senders.size();
        for (std::size_t i = 0; i < senders.size(); ++i) {
          if (senders[i]->topic == topic) index = i;
        }
        if (index == senders.size()) {
          WithTopicType(topic, [&](auto msg) {
            auto sender = std::make_unique<TypedMcapSender<decltype(msg)>>();
            sender->writer = node.CreateWriter<decltype(msg)>();
            sender->writer->SetFlowControl(500, std::chrono::seconds(10));
            sender->topic = topic;
            senders.push_back(std::move(sender));
          });
        }
        sender_of[m.channel_id] = index;
      }
    }
    auto it = sender_of.find(m.channel_id);
    if (it == sender_of.end()) {
      ++skipped;
      return;
    }
    std::uint64_t stamp = 0;
    if (!senders[it->second]->Check(m.data, &stamp)) {
      throw InputError(a.input + ": a message on magnav/" + senders[it->second]->topic + " (log time " +
                       std::to_string(m.log_time) + " ns) is not CDR of " + TypeNameOf(senders[it->second]->topic));
    }
    stamp_min = std::min(stamp_min, stamp);
    stamp_max = std::max(stamp_max, stamp);
    events.push_back({it->second, m.log_time, m.data});
  });
  if (!summary.truncated.empty()) std::fprintf(stderr, "replay: warning: %s\n", summary.truncated.c_str());
  if (events.empty()) throw InputError(a.input + ": no message on the topics to replay (--topic; default: the sensor topics)");
  // Receive order may differ from log_time order by a little (several
  // receive threads): time order, stable.
  std::stable_sort(events.begin(), events.end(), [](const McapEvent& x, const McapEvent& y) { return x.log_time < y.log_time; });
  const auto wait = std::chrono::milliseconds(static_cast<long>(a.wait_s * 1000));
  for (auto& s : senders) {
    if (a.wait_readers > 0 && !s->WaitForMatched(a.wait_readers, wait)) {
      throw InputError("replay: no reader of magnav/" + s->topic + " appeared within " + FormatNumber(a.wait_s) +
                       " s (domain " + std::to_string(node.domain_id()) + ")");
    }
  }
  Settle(a);
  // --loop: each pass shifted by the span plus one interval (of log times
  // for the pacing, of the messages' stamps for their contents).
  auto step_after = [](std::uint64_t span, std::size_t n) { return n > 1 ? span / (n - 1) : 0; };
  const std::uint64_t log0 = events.front().log_time;
  const std::uint64_t log_span = events.back().log_time - log0;
  const std::uint64_t log_period = log_span + step_after(log_span, events.size());
  const std::uint64_t stamp_span = stamp_max - stamp_min;
  const std::uint64_t stamp_period = stamp_span + step_after(stamp_span, events.size());
  cli::Progress progress("replay", "messages", a.loop ? 0 : events.size());
  const auto t0 = std::chrono::steady_clock::now();
  std::size_t sent = 0;
  for (int pass = 0; pass == 0 || (a.loop && !dds::ShutdownRequested()); ++pass) {
    for (const McapEvent& e : events) {
      if (dds::ShutdownRequested()) break;
      if (a.speed > 0) {
        const double at_s = static_cast<double>(e.log_time - log0 + static_cast<std::uint64_t>(pass) * log_period) * 1e-9;
        std::this_thread::sleep_until(t0 + std::chrono::duration<double>(at_s / a.speed));
      }
      if (!senders[e.topic]->Send(e.data, static_cast<std::uint64_t>(pass) * stamp_period, pass)) {
        throw InputError("replay: the middleware refused a sample");
      }
      progress.Update(++sent);
    }
  }
  progress.Done();
  bool acked = true;
  for (auto& s : senders) acked = s->WaitForAcknowledgments() && acked;
  WarnIfNotAcknowledged(acked);
  std::string per_topic;
  for (auto& s : senders) {
    if (!per_topic.empty()) per_topic += ", ";
    per_topic += std::to_string(s->sent) + " " + s->topic;
  }
  std::printf("replayed %zu messages (%s) from %s on domain %d\n", sent, per_topic.c_str(), a.input.c_str(),
              node.domain_id());
  if (skipped) std::fprintf(stderr, "replay: %llu message(s) of other topics not sent (--topic)\n", static_cast<unsigned long long>(skipped));
}

void Run(const ReplayArgs& a) {
  if (!a.input.empty() && (mcap::HasMcapMagic(a.input) || (a.input.size() > 5 && a.input.compare(a.input.size() - 5, 5, ".mcap") == 0))) {
    if (!a.magnetometer.empty() || !a.map_path.empty() || !a.gnss.empty()) throw InputError("replay: an MCAP --input goes alone");
    RunMcap(a);
    return;
  }
  if (!a.topics.empty()) throw InputError("replay: --topic goes with an MCAP --input");
  if (a.loop && a.input.empty()) throw InputError("replay: --loop goes with --input (a gradiometer file or MCAP recording)");
  if (!a.map_path.empty()) {
    if (!a.input.empty() || !a.magnetometer.empty()) throw InputError("replay: --map-path goes alone");
    RunLocalizeStreams(a, ReadMapRunEvents(a), true);
    return;
  }
  if (!a.magnetometer.empty()) {
    if (!a.input.empty()) throw InputError("replay: give --input or --magnetometer, not both");
    RunLocalizeStreams(a, ReadLocalizeEvents(a.magnetometer, a.gnss), !a.gnss.empty());
    return;
  }
  if (!a.gnss.empty()) throw InputError("replay: --gnss goes with --magnetometer");
  if (a.input.empty()) throw InputError("replay: give --input (gradiometer file) or --magnetometer");
  const GradiometerFile file = ReadGradiometerFile(a.input);
  dds::InstallShutdownHandlers();
  dds::Node node(a.dds.ToNodeOptions("magnav_replay"));
  auto writer = node.CreateWriter<dds::msg::GradiometerSample>();
  // Never outrun the readers' acknowledgments by more than half the stream
  // history (config/magnav_profiles.xml: KEEP_LAST 1000 per sensor).
  writer->SetFlowControl(500, std::chrono::seconds(10));
  const auto wait = std::chrono::milliseconds(static_cast<long>(a.wait_s * 1000));
  if (a.wait_readers > 0 && !writer->WaitForMatched(a.wait_readers, wait)) {
    throw InputError("replay: no reader of magnav/gradiometer appeared within " + FormatNumber(a.wait_s) +
                     " s (domain " + std::to_string(node.domain_id()) + ")");
  }
  Settle(a);
  std::unordered_map<std::uint32_t, std::uint64_t> seq;
  const auto t0 = std::chrono::steady_clock::now();
  const double file_t0 = file.samples.empty() ? 0.0 : file.samples.front().t_s;
  // With --loop each pass is shifted by the file's span plus one sample
  // interval, so time keeps going forward for the consumers.
  double span_s = 0.0;
  if (file.samples.size() > 1) {
    const double last = file.samples.back().t_s;
    double step = 0.0;
    for (std::size_t i = 1; i < file.samples.size() && step == 0.0; ++i) step = file.samples[i].t_s - file_t0;
    span_s = last - file_t0 + step;
  }
  cli::Progress progress("replay", "samples", a.loop ? 0 : file.samples.size());
  std::size_t sent = 0;
  for (int pass = 0; pass == 0 || (a.loop && !dds::ShutdownRequested()); ++pass) {
    for (GradiometerSample s : file.samples) {
      if (dds::ShutdownRequested()) break;
      s.t_s += pass * span_s;
      if (a.speed > 0) {
        const auto due = t0 + std::chrono::duration<double>((s.t_s - file_t0) / a.speed);
        std::this_thread::sleep_until(due);
      }
      if (!writer->Write(dds::ToMsg(s, seq[s.sensor_id]++))) {
        throw InputError("replay: the middleware refused a sample");
      }
      progress.Update(++sent);
    }
  }
  progress.Done();
  WarnIfNotAcknowledged(writer->WaitForAcknowledgments(std::chrono::seconds(10)));
  std::printf("replayed %zu samples from %s on domain %d\n", sent, a.input.c_str(), node.domain_id());
}

}  // namespace

void AddReplayCommand(CLI::App& app) {
  auto args = std::make_shared<ReplayArgs>();
  CLI::App* sub = app.add_subcommand(
      "replay",
      "Publish a gradiometer CSV on magnav/gradiometer, localize files or a map-matching run on magnav/magnetometer + "
      "magnav/vessel_nav");
  sub->add_option("--input", args->input,
                  "gradiometer CSV (t,sensor_id,sensor_*,B_*,T00..T22; a CSV recording's DIR/gradiometer.csv from `magnav record "
                  "--output-dir DIR` is one: its extra columns are ignored), or an MCAP recording (magnav record --output "
                  "FILE.mcap: its sensor topics, or --topic, paced by their receive times). A CSV recording directory "
                  "is not taken whole: give its files (--input DIR/gradiometer.csv, or --magnetometer "
                  "DIR/magnetometer.csv --gnss DIR/vessel_nav.csv)");
  sub->add_option("--topic", args->topics,
                  "MCAP input: the topics to send (gradiometer, magnetometer, vessel_nav, dipole_fix, track, "
                  "sensor_position, map_fix, all; default: the sensor topics gradiometer, magnetometer, vessel_nav)")
      ->delimiter(',')
      ->check(CLI::IsMember(TopicChoices()));
  sub->add_option("--magnetometer", args->magnetometer,
                  "localize measurements CSV (t,sensor_id,B_x,B_y,B_z; or a CSV recording's magnetometer.csv) -> "
                  "magnav/magnetometer");
  sub->add_option("--gnss", args->gnss, "with --magnetometer: GNSS CSV (t,x,y,sigma; or a CSV recording's vessel_nav.csv) -> magnav/vessel_nav");
  sub->add_option("--map-path", args->map_path,
                  "map-matching run (k,ins_lat,ins_lon and --meas-column, as `magnav match` reads) -> magnav/vessel_nav "
                  "(INS, geodetic) + magnav/magnetometer (|B| = --reference-field + anomaly)");
  sub->add_option("--meas-column", args->meas_column, "with --map-path: the measured anomaly column, nT");
  sub->add_option("--reference-field", args->reference_field_nT,
                  "with --map-path: the map's reference field |F0|, nT (required with it)");
  sub->add_option("--step-period", args->step_period_s, "with --map-path: seconds between path points");
  sub->add_option("--vehicle-id", args->vehicle_id, "with --map-path: vessel_id and sensor_id of the messages");
  sub->add_option("--speed", args->speed, "time factor (1 = real time, 10 = ten times faster, 0 = no pacing)")
      ->check(CLI::NonNegativeNumber);
  sub->add_flag("--loop", args->loop,
               "with --input: replay the file over and over until stopped (SIGINT/SIGTERM), each pass shifted in time "
               "by the file's span so that time keeps going forward (MCAP: sequence numbers too)");
  sub->add_option("--wait-readers", args->wait_readers, "wait for this many readers before sending");
  sub->add_option("--wait", args->wait_s, "how long to wait for readers, s");
  sub->add_option("--settle", args->settle_s,
                  "after the readers matched, wait this long before the first sample, s: a VOLATILE reader of another "
                  "vendor may not have matched this writer yet (TRANSIENT_LOCAL readers need none; docs/INTEROP.md)")
      ->check(CLI::NonNegativeNumber);
  AddDdsOptions(*sub, &args->dds);
  sub->callback([args] { Run(*args); });
}

}  // namespace magnav::tools
