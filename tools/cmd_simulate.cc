// magnav simulate: write a vessel pass (and its truth) in the reference format.
#include <memory>

#include "commands.h"
#include "magnav/core/csv.h"
#include "magnav/core/error.h"
#include "magnav/core/simulate.h"

namespace magnav::tools {
namespace {

struct SimulateArgs {
  std::string output, truth, noise = "none", turns, sensors;
  Vec3Arg moment, start, b0;
  double speed = -1, heading = 1e9, rate = -1, sigma_B = -1, sigma_T = -1;
  std::uint64_t seed = 1;
};

// "80:0,60:0.02,60:0" -> segments
std::vector<TurnSegment> ParseTurns(const std::string& s) {
  std::vector<TurnSegment> out;
  std::size_t pos = 0;
  while (pos <= s.size()) {
    const std::size_t comma = s.find(',', pos);
    const std::string item = s.substr(pos, comma == std::string::npos ? std::string::npos : comma - pos);
    const std::size_t colon = item.find(':');
    const auto d = colon == std::string::npos ? std::nullopt : ParseNumber(item.substr(0, colon));
    const auto w = colon == std::string::npos ? std::nullopt : ParseNumber(item.substr(colon + 1));
    if (!d || !w) throw InputError("--turns: '" + item + "' is not DURATION_S:TURN_RATE_RPS");
    out.push_back({*d, *w});
    if (comma == std::string::npos) break;
    pos = comma + 1;
  }
  return out;
}

void Run(const SimulateArgs& a) {
  PassScenario sc;
  if (a.noise == "fluxgate") {
    sc.sigma_B = 1e-9;
    sc.sigma_T = 1.4e-9;
  } else if (a.noise == "squid") {
    sc.sigma_B = 1e-13;
    sc.sigma_T = 1e-13;
  }
  if (a.sigma_B >= 0) sc.sigma_B = a.sigma_B;
  if (a.sigma_T >= 0) sc.sigma_T = a.sigma_T;
  if (a.moment.set) sc.moment_body = {a.moment.v[0], a.moment.v[1], a.moment.v[2]};
  if (a.start.set) sc.start_position = {a.start.v[0], a.start.v[1], a.start.v[2]};
  if (a.b0.set) sc.B0 = {a.b0.v[0], a.b0.v[1], a.b0.v[2]};
  if (a.speed >= 0) sc.speed_mps = a.speed;
  if (a.heading < 1e8) sc.start_heading_rad = a.heading;
  if (a.rate > 0) sc.rate_hz = a.rate;
  if (!a.turns.empty()) sc.segments = ParseTurns(a.turns);
  if (!a.sensors.empty()) sc.sensors = cli::ParseVec3List("--sensors", a.sensors);
  sc.seed = a.seed;
  const SimulatedPass pass = SimulatePass(sc);
  WritePassCsv(a.output, sc, pass);
  if (!a.truth.empty()) WriteTruthCsv(a.truth, sc, pass);
  std::printf("wrote %zu samples (%zu instants, %zu sensors) to %s\n", pass.samples.size(), pass.truth.size(),
              sc.sensors.size(), a.output.c_str());
}

}  // namespace

void AddSimulateCommand(CLI::App& app) {
  auto args = std::make_shared<SimulateArgs>();
  CLI::App* sub = app.add_subcommand(
      "simulate", "Simulate a vessel dipole passing fixed gradiometers (defaults: the reference AUV pass)");
  sub->add_option("--output", args->output, "pass CSV to write")->required();
  sub->add_option("--truth", args->truth, "truth CSV to write");
  sub->add_option("--noise", args->noise, "noise level: none, fluxgate (1 nT, 1.4 nT/m), squid (0.1 pT, 0.1 pT/m)")
      ->check(CLI::IsMember({"none", "fluxgate", "squid"}));
  sub->add_option("--sigma-b", args->sigma_B, "B noise per axis, T (overrides --noise)");
  sub->add_option("--sigma-t", args->sigma_T, "tensor noise per element, T/m (overrides --noise)");
  AddVec3Option(*sub, "--moment-body", &args->moment, "body moment, A*m^2 (x fwd, y starboard, z down)");
  AddVec3Option(*sub, "--start", &args->start, "start position NED, m");
  AddVec3Option(*sub, "--b0", &args->b0, "background field NED, T");
  sub->add_option("--speed", args->speed, "speed, m/s");
  sub->add_option("--heading", args->heading, "start heading, rad from north clockwise");
  sub->add_option("--turns", args->turns, "segments DURATION_S:TURN_RATE_RPS,... (default 80:0,60:0.02,60:0)");
  sub->add_option("--sensors", args->sensors, "sensor positions X,Y,Z;X,Y,Z... NED m (default 0,0,0)");
  sub->add_option("--rate", args->rate, "sample rate, Hz (default 10)");
  sub->add_option("--seed", args->seed, "noise seed");
  sub->callback([args] { Run(*args); });
}

}  // namespace magnav::tools
