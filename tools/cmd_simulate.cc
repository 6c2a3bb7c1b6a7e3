// magnav simulate: write a vessel pass (and its truth) in the reference format,
// or (--vessel repeated) a sensor field crossed by several vessels.
#include <cmath>
#include <memory>

#include "commands.h"
#include "magnav/core/csv.h"
#include "magnav/core/error.h"
#include "magnav/core/simulate.h"
#include "magnav/cli/scenario_file.h"

namespace magnav::tools {
namespace {

struct SimulateArgs {
  std::string output, truth, noise = "none", turns, sensors, grid, scenario;
  std::vector<std::string> vessels;
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

// "id=2;t0=120;start=38,100,-6;speed=1.2;heading=-1.5708;moment=1800,-500,700;turns=140:0"
// -> a field vessel (keys left out keep FieldVessel's defaults; id defaults
// to the position in the list, from 1).
FieldVessel ParseVessel(const std::string& spec, std::size_t index) {
  FieldVessel v;
  v.vessel_id = static_cast<std::uint32_t>(index + 1);
  const auto fail = [&](const std::string& why) {
    throw InputError("--vessel '" + spec + "': " + why +
                     " (expected KEY=VALUE;... with keys id, t0, start, speed, heading, moment, turns)");
  };
  std::size_t pos = 0;
  while (pos < spec.size()) {
    std::size_t end = spec.find(';', pos);
    if (end == std::string::npos) end = spec.size();
    const std::string item = spec.substr(pos, end - pos);
    pos = end + 1;
    if (item.empty()) continue;
    const std::size_t eq = item.find('=');
    if (eq == std::string::npos) fail("'" + item + "' has no '='");
    const std::string key = item.substr(0, eq), value = item.substr(eq + 1);
    const auto number = [&]() {
      const auto x = ParseNumber(value);
      if (!x) fail(key + ": '" + value + "' is not a number");
      return *x;
    };
    const auto vec3 = [&]() {
      const auto x = ParseNumberList(value);
      if (!x || x->size() != 3) fail(key + ": '" + value + "' is not X,Y,Z");
      return Eigen::Vector3d((*x)[0], (*x)[1], (*x)[2]);
    };
    if (key == "id") {
      const double id = number();
      if (!(id >= 1.0) || id != std::floor(id) || id > 4e9) fail("id must be a whole number >= 1");
      v.vessel_id = static_cast<std::uint32_t>(id);
    } else if (key == "t0") {
      v.t_start_s = number();
    } else if (key == "start") {
      v.start_position = vec3();
    } else if (key == "speed") {
      v.speed_mps = number();
    } else if (key == "heading") {
      v.start_heading_rad = number();
    } else if (key == "moment") {
      v.moment_body = vec3();
    } else if (key == "turns") {
      v.segments = ParseTurns(value);
    } else {
      fail("unknown key '" + key + "'");
    }
  }
  return v;
}

// Several vessels (--vessel repeated) over the sensors or a grid.
void RunField(const SimulateArgs& a, double sigma_B, double sigma_T) {
  if (a.moment.set || a.start.set || a.speed >= 0 || a.heading < 1e8 || !a.turns.empty()) {
    throw InputError("--vessel describes each vessel: --moment-body, --start, --speed, --heading and --turns are "
                     "for a single-vessel pass");
  }
  FieldScenario sc;
  for (std::size_t i = 0; i < a.vessels.size(); ++i) sc.vessels.push_back(ParseVessel(a.vessels[i], i));
  sc.sigma_B = sigma_B;
  sc.sigma_T = sigma_T;
  if (a.b0.set) sc.B0 = a.b0.value();
  if (a.rate > 0) sc.rate_hz = a.rate;
  if (!a.sensors.empty() && !a.grid.empty()) throw InputError("--sensors and --grid: give one of them");
  if (!a.grid.empty()) {
    const auto g = ParseNumberList(a.grid);
    if (!g || g->size() != 3 || (*g)[0] < 1 || (*g)[1] < 1 || (*g)[0] != std::floor((*g)[0]) ||
        (*g)[1] != std::floor((*g)[1]) || (*g)[0] * (*g)[1] > 10000 || !((*g)[2] > 0.0)) {
      throw InputError("--grid: expected NX,NY,SPACING_M (whole NX, NY >= 1, NX*NY <= 10000, spacing > 0), got '" +
                       a.grid + "'");
    }
    sc.sensors = SensorGrid(static_cast<int>((*g)[0]), static_cast<int>((*g)[1]), (*g)[2]);
  } else if (!a.sensors.empty()) {
    sc.sensors = cli::ParseVec3List("--sensors", a.sensors);
  } else {
    sc.sensors = SensorGrid(3, 3, 40.0);
  }
  sc.seed = a.seed;
  const SimulatedField field = SimulateField(sc);
  WriteFieldPassCsv(a.output, sc, field);
  if (!a.truth.empty()) WriteFieldTruthCsv(a.truth, sc, field);
  std::printf("wrote %zu samples (%zu sensors, %zu vessels, %s s) to %s\n", field.samples.size(), sc.sensors.size(),
              sc.vessels.size(), FormatNumber(sc.duration_s()).c_str(), a.output.c_str());
}

// A field from a scenario file (cli/scenario_file.h).
void RunScenario(const SimulateArgs& a, std::size_t other_options) {
  if (other_options > 0) {
    throw InputError("--scenario describes the whole field: give only --output and --truth with it");
  }
  const FieldScenario sc = cli::ReadScenarioFile(a.scenario);
  const SimulatedField field = SimulateField(sc);
  WriteFieldPassCsv(a.output, sc, field);
  if (!a.truth.empty()) WriteFieldTruthCsv(a.truth, sc, field);
  std::printf("wrote %zu samples (%zu sensors, %zu vessels, %s s) to %s\n", field.samples.size(), sc.sensors.size(),
              sc.vessels.size(), FormatNumber(sc.duration_s()).c_str(), a.output.c_str());
}

void Run(const SimulateArgs& a, std::size_t other_options) {
  RefuseOutputOverInput(a.truth, {a.output});
  RefuseOutputOverInput(a.output, {a.scenario});
  RefuseOutputOverInput(a.truth, {a.scenario});
  if (!a.scenario.empty()) return RunScenario(a, other_options);
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
  if (!a.vessels.empty()) return RunField(a, sc.sigma_B, sc.sigma_T);
  if (!a.grid.empty()) throw InputError("--grid is for a field: give the vessels with --vessel");
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
  sub->add_option("--vessel", args->vessels,
                  "a field with several vessels, this option once per vessel: "
                  "'id=N;t0=S;start=X,Y,Z;speed=M/S;heading=RAD;moment=MX,MY,MZ;turns=D:W,...' (keys optional; t0 = "
                  "time it appears, s; it exists for its turns' total duration); the truth gets a vessel_id column")
      ->take_all();
  sub->add_option("--grid", args->grid,
                  "with --vessel: an NX x NY sensor grid at z = 0 centred on the origin, NX,NY,SPACING_M (default "
                  "3,3,40 as the reference field; or --sensors)");
  sub->add_option("--seed", args->seed, "noise seed");
  sub->add_option("--scenario", args->scenario,
                  "a field from a scenario file (TOML: sensors, noise, background drift, [vessel.ID] sections with "
                  "start and velocity, turns or waypoints; see cli/include/magnav/cli/scenario_file.h and "
                  "tests/data/generated/scenarios/); only --output and --truth go with it");
  sub->callback([args, sub] {
    std::size_t others = 0;
    for (const char* name : {"--noise", "--sigma-b", "--sigma-t", "--moment-body", "--start", "--b0", "--speed",
                             "--heading", "--turns", "--sensors", "--rate", "--vessel", "--grid", "--seed"}) {
      others += sub->get_option(name)->count();
    }
    Run(*args, others);
  });
}

}  // namespace magnav::tools
