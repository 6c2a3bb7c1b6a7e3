// magnav replay: publish a gradiometer file onto magnav/gradiometer, paced by
// its time column (or as fast as the reliable stream allows).
#include <chrono>
#include <memory>
#include <thread>
#include <unordered_map>

#include "commands.h"
#include "magnav/core/csv.h"
#include "magnav/core/error.h"
#include "magnav/core/gradiometer.h"
#include "magnav/dds/convert.h"
#include "magnav/dds/node.h"
#include "magnav/dds/shutdown.h"

namespace magnav::tools {
namespace {

struct ReplayArgs {
  std::string input;
  double speed = 1.0;           // time factor; 0 = as fast as possible
  int wait_readers = 1;
  double wait_s = 10.0;
  DdsArgs dds;
};

void Run(const ReplayArgs& a) {
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
  std::unordered_map<std::uint32_t, std::uint64_t> seq;
  const auto t0 = std::chrono::steady_clock::now();
  const double file_t0 = file.samples.empty() ? 0.0 : file.samples.front().t_s;
  std::size_t sent = 0;
  for (const GradiometerSample& s : file.samples) {
    if (dds::ShutdownRequested()) break;
    if (a.speed > 0) {
      const auto due = t0 + std::chrono::duration<double>((s.t_s - file_t0) / a.speed);
      std::this_thread::sleep_until(due);
    }
    if (!writer->Write(dds::ToMsg(s, seq[s.sensor_id]++))) {
      throw InputError("replay: a reader did not acknowledge samples within 10 s (too slow or gone)");
    }
    ++sent;
  }
  writer->WaitForAcknowledgments(std::chrono::seconds(10));
  std::printf("replayed %zu samples from %s on domain %d\n", sent, a.input.c_str(), node.domain_id());
}

}  // namespace

void AddReplayCommand(CLI::App& app) {
  auto args = std::make_shared<ReplayArgs>();
  CLI::App* sub = app.add_subcommand("replay", "Publish a gradiometer CSV file on the magnav/gradiometer topic");
  sub->add_option("--input", args->input, "gradiometer CSV (t,sensor_id,sensor_*,B_*,T00..T22)")->required();
  sub->add_option("--speed", args->speed, "time factor (1 = real time, 10 = ten times faster, 0 = no pacing)")
      ->check(CLI::NonNegativeNumber);
  sub->add_option("--wait-readers", args->wait_readers, "wait for this many readers before sending");
  sub->add_option("--wait", args->wait_s, "how long to wait for readers, s");
  AddDdsOptions(*sub, &args->dds);
  sub->callback([args] { Run(*args); });
}

}  // namespace magnav::tools
