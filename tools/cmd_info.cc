// `magnav info FILE`: what a recording holds (MCAP, or a CSV of `magnav
// record` / a pass): per topic the message count, time span and rate, the
// sensors / tracks / vehicles, missing sequence numbers and time gaps.
// `magnav export FILE.mcap --output-dir D`: the CSVs `magnav record` would
// have written, one TOPIC.csv per topic.
#include <algorithm>
#include <cmath>
#include <cstdio>
#include <filesystem>
#include <map>
#include <memory>

#include "commands.h"
#include "magnav/core/csv.h"
#include "magnav/core/error.h"
#include "magnav/mcap/mcap.h"
#include "mcap_topics.h"
#include "record_rows.h"

namespace magnav::tools {
namespace {

// One stream (a key of a topic): times and sequence numbers.
struct KeyStats {
  std::uint64_t count = 0;
  double first_t = 0, last_t = 0;
  std::vector<double> dts;
  std::int64_t last_seq = -1;
  std::uint64_t missing = 0, back = 0;
  void Add(double t, std::int64_t seq) {
    if (count == 0) {
      first_t = last_t = t;
    } else {
      dts.push_back(t - last_t);
      last_t = t;
    }
    if (seq >= 0) {
      if (last_seq >= 0 && seq > last_seq + 1) missing += static_cast<std::uint64_t>(seq - last_seq - 1);
      if (last_seq >= 0 && seq <= last_seq) ++back;
      last_seq = seq;
    }
    ++count;
  }
};

struct TopicStats {
  std::string name, type, key_name = "keys";
  std::uint64_t count = 0;
  std::map<std::uint32_t, KeyStats> keys;
  std::uint64_t undecodable = 0;
};

// Ten significant digits: 71.1 s, not 71.10000000000001 s.
std::string Num(double v) {
  char b[32];
  std::snprintf(b, sizeof b, "%.10g", v);
  return b;
}

// Time gaps: intervals more than 3 times the stream's median interval.
void Print(const std::vector<TopicStats>& topics) {
  for (const TopicStats& t : topics) {
    double first = 0, last = 0;
    bool any = false;
    std::uint64_t missing = 0, back = 0;
    std::vector<std::string> gaps;
    std::string ids;
    for (const auto& [k, s] : t.keys) {
      first = any ? std::min(first, s.first_t) : s.first_t;
      last = any ? std::max(last, s.last_t) : s.last_t;
      any = true;
      missing += s.missing;
      back += s.back;
      if (!ids.empty()) ids += ",";
      ids += std::to_string(k);
      std::vector<double> d = s.dts;
      if (d.size() >= 2) {
        std::nth_element(d.begin(), d.begin() + static_cast<long>(d.size() / 2), d.end());
        const double median = d[d.size() / 2];
        double t = s.first_t;
        for (double dt : s.dts) {
          if (median > 0 && dt > 3 * median && gaps.size() < 10) {
            gaps.push_back(std::to_string(k) + ": " + Num(t) + ".." + Num(t + dt) + " s");
          }
          t += dt;
        }
      }
    }
    const double span = last - first;
    std::printf("%s%s: %llu message(s)", t.name.c_str(), t.type.empty() ? "" : (" (" + t.type + ")").c_str(),
                static_cast<unsigned long long>(t.count));
    if (any) {
      std::printf(", t %s .. %s s (%s s)", Num(first).c_str(), Num(last).c_str(), Num(span).c_str());
      if (span > 0) std::printf(", %s msg/s", Num(static_cast<double>(t.count - 1) / span).c_str());
      std::printf("\n  %s (%zu): %s\n", t.key_name.c_str(), t.keys.size(), ids.c_str());
      std::printf("  missing by seq: %llu%s; time gaps (> 3x median interval): %s\n",
                  static_cast<unsigned long long>(missing),
                  back ? (", " + std::to_string(back) + " step(s) back").c_str() : "",
                  gaps.empty() ? "none" : "");
      for (const std::string& g : gaps) std::printf("    %s\n", g.c_str());
    } else {
      std::printf("\n");
    }
    if (t.undecodable)
      std::printf("  %llu message(s) not CDR of the type\n", static_cast<unsigned long long>(t.undecodable));
  }
}

const char* KeyName(const std::string& topic) {
  if (topic == "track") return "tracks";
  if (topic == "vessel_nav") return "vessels";
  if (topic == "map_fix") return "vehicles";
  return "sensors";
}

void InfoMcap(const std::string& path) {
  std::map<std::uint16_t, TopicStats> by_channel;
  std::uint64_t first_log = 0, last_log = 0, n = 0;
  const mcap::ReadSummary s = mcap::Read(path, [&](const mcap::Message& m, const mcap::ReadSummary& sum) {
    if (n++ == 0) first_log = m.log_time;
    first_log = std::min(first_log, m.log_time);
    last_log = std::max(last_log, m.log_time);
    TopicStats& t = by_channel[m.channel_id];
    const mcap::Channel* c = mcap::FindChannel(sum, m.channel_id);
    if (t.name.empty()) {
      t.name = c->topic;
      const mcap::Schema* sc = mcap::FindSchema(sum, c->schema_id);
      t.type = sc ? sc->name : "";
      t.key_name = KeyName(ShortTopic(c->topic));
    }
    ++t.count;
    const std::string topic = ShortTopic(c->topic);
    if (topic.empty() || c->message_encoding != "cdr") return;
    WithTopicType(topic, [&](auto msg) {
      if (!FromCdr(m.data, &msg)) {
        ++t.undecodable;
        return;
      }
      t.keys[KeyOf(msg)].Add(static_cast<double>(msg.stamp_ns()) * 1e-9, SeqOf(msg));
    });
  });
  std::printf("%s: MCAP (profile '%s', written by '%s'), %zu channel(s), %llu message(s) in %u chunk(s)\n",
              path.c_str(), s.profile.c_str(), s.library.c_str(), s.channels.size(),
              static_cast<unsigned long long>(s.messages), s.chunks);
  if (n > 0) {
    std::printf("received (log_time) over %.3f s\n", static_cast<double>(last_log - first_log) * 1e-9);
  }
  for (const mcap::Metadata& m : s.metadata) {
    std::printf("metadata %s:", m.name.c_str());
    for (const auto& [k, v] : m.values) std::printf(" %s=%s;", k.c_str(), v.c_str());
    std::printf("\n");
  }
  std::vector<TopicStats> topics;
  for (const mcap::Channel& c : s.channels) {
    auto it = by_channel.find(c.id);
    if (it == by_channel.end()) {
      TopicStats t;
      t.name = c.topic;
      const mcap::Schema* sc = mcap::FindSchema(s, c.schema_id);
      t.type = sc ? sc->name : "";
      topics.push_back(t);
    } else {
      topics.push_back(it->second);
    }
  }
  Print(topics);
  if (!s.truncated.empty()) std::fprintf(stderr, "info: warning: %s\n", s.truncated.c_str());
}

void InfoCsv(const std::string& path) {
  const CsvTable t = CsvTable::Read(path);
  TopicStats s;
  s.name = path;
  const auto& cols = t.header();
  auto has = [&](const std::string& c) { return std::find(cols.begin(), cols.end(), c) != cols.end(); };
  if (!has("t"))
    throw InputError(path + ": no column 't' (info reads recordings and passes with a time column)");
  std::string key;
  for (const char* k : {"sensor_id", "track_id", "vehicle_id", "vessel_id", "vessel"}) {
    if (has(k)) {
      key = k;
      break;
    }
  }
  s.key_name = key.empty()           ? "keys"
               : key == "track_id"   ? "tracks"
               : key == "vehicle_id" ? "vehicles"
               : key == "sensor_id"  ? "sensors"
                                     : "vessels";
  const std::size_t tc = t.column("t");
  const std::size_t kc = key.empty() ? 0 : t.column(key);
  const bool seq = has("seq");
  const std::size_t sc = seq ? t.column("seq") : 0;
  for (std::size_t i = 0; i < t.num_rows(); ++i) {
    const std::uint32_t k = key.empty() ? 0 : t.uint32(i, kc);
    s.keys[k].Add(t.number(i, tc), seq ? static_cast<std::int64_t>(t.number(i, sc)) : -1);
    ++s.count;
  }
  std::printf("%s: CSV, %zu column(s), %zu row(s)\n", path.c_str(), cols.size(), t.num_rows());
  Print({s});
}

void RunInfo(const std::string& path) {
  if (mcap::HasMcapMagic(path) || (path.size() > 5 && path.compare(path.size() - 5, 5, ".mcap") == 0)) {
    InfoMcap(path);
  } else {
    InfoCsv(path);
  }
}

void RunExport(const std::string& path, const std::string& dir) {
  // The directory is made with the first CSV; after an error a directory
  // made here is removed again (the CSVs are temporaries until the end).
  bool made_dir = false;
  auto make_dir = [&] {
    if (std::filesystem::is_directory(dir)) return;
    std::error_code ec;
    made_dir = std::filesystem::create_directories(dir, ec);
    if (ec || !std::filesystem::is_directory(dir))
      throw InputError("--output-dir: cannot create directory '" + dir + "'");
  };
  std::map<std::uint16_t, std::unique_ptr<CsvWriter>> out;
  std::map<std::uint16_t, std::string> topic_of;
  std::map<std::string, std::uint64_t> rows;
  std::uint64_t skipped = 0;
  mcap::ReadSummary s;
  try {
    s = mcap::Read(path, [&](const mcap::Message& m, const mcap::ReadSummary& sum) {
      auto it = topic_of.find(m.channel_id);
      if (it == topic_of.end()) {
        const mcap::Channel* c = mcap::FindChannel(sum, m.channel_id);
        std::string topic = c->message_encoding == "cdr" ? ShortTopic(c->topic) : "";
        if (!topic.empty()) {
          for (const auto& [id, other] : topic_of) {
            if (other == topic)
              throw InputError(path + ": two channels of topic " + c->topic +
                               " (export writes one CSV per topic)");
          }
          const std::string file = dir + "/" + topic + ".csv";
          make_dir();
          RefuseOutputOverInput(file, {path});
          out[m.channel_id] = std::make_unique<CsvWriter>(file, Header(topic));
        }
        it = topic_of.emplace(m.channel_id, topic).first;
      }
      if (it->second.empty()) {
        ++skipped;
        return;
      }
      WithTopicType(it->second, [&](auto msg) {
        if (!FromCdr(m.data, &msg)) {
          throw InputError(path + ": a message on magnav/" + it->second + " (log time " +
                           std::to_string(m.log_time) + " ns) is not CDR of " + TypeNameOf(it->second));
        }
        out[m.channel_id]->WriteRow(Row(msg));
        ++rows[it->second];
      });
    });
    make_dir();
    // A topic recorded without messages: its CSV with the header alone, as
    // record writes it.
    for (const mcap::Channel& c : s.channels) {
      const std::string topic = c.message_encoding == "cdr" ? ShortTopic(c.topic) : "";
      if (topic.empty() || topic_of.count(c.id) || rows.count(topic)) continue;
      bool taken = false;
      for (const auto& [id, other] : topic_of) taken = taken || other == topic;
      if (taken) continue;
      topic_of[c.id] = topic;
      rows[topic] = 0;
      out[c.id] = std::make_unique<CsvWriter>(dir + "/" + topic + ".csv", Header(topic));
    }
    for (auto& [id, w] : out) w->Close();
  } catch (...) {
    out.clear();  // the temporaries go
    std::error_code ec;
    if (made_dir) std::filesystem::remove(dir, ec);
    throw;
  }
  for (const auto& [t, n] : rows)
    std::printf("exported %llu %s row(s) to %s/%s.csv\n", static_cast<unsigned long long>(n), t.c_str(),
                dir.c_str(), t.c_str());
  if (skipped)
    std::fprintf(stderr, "export: %llu message(s) on channels that are not magnav topics in CDR skipped\n",
                 static_cast<unsigned long long>(skipped));
  if (!s.truncated.empty()) std::fprintf(stderr, "export: warning: %s\n", s.truncated.c_str());
}

}  // namespace

void AddInfoCommand(CLI::App& app) {
  auto path = std::make_shared<std::string>();
  CLI::App* sub = app.add_subcommand(
      "info", "What a recording holds (MCAP or CSV): topics, counts, time span, rate, sensors/tracks, gaps");
  sub->add_option("file", *path, "an MCAP recording (magnav record --output FILE.mcap) or a CSV")->required();
  sub->callback([path] { RunInfo(*path); });
}

void AddExportCommand(CLI::App& app) {
  auto path = std::make_shared<std::string>();
  auto dir = std::make_shared<std::string>();
  CLI::App* sub =
      app.add_subcommand("export", "Write an MCAP recording's topics as the CSVs magnav record writes");
  sub->add_option("file", *path, "MCAP recording")->required();
  sub->add_option("--output-dir", *dir, "directory (made if missing): one TOPIC.csv per topic")->required();
  sub->callback([path, dir] { RunExport(*path, *dir); });
}

}  // namespace magnav::tools
